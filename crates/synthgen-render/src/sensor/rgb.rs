//! RGB sensor effects in linear light: exposure jitter, white balance error, vignetting,
//! defocus by depth (thin-lens circle of confusion), motion blur (a straight streak), Gaussian
//! blur (optics), shot noise (variance proportional to the signal) and read noise; then JPEG
//! compression of the 8-bit frame.

use rand::{Rng, RngCore};
use rand_chacha::ChaCha8Rng;
use synthgen_core::scene::RgbNoiseSpec;

use crate::color::{srgb_index, ColorLuts, TO_SRGB_MAX};

/// Applies the RGB effects to `rgb` (sRGB bytes, `w` x `h` x 3) in place: per frame an
/// exposure factor 2^s (s uniform in `exposure_stops`) and a blur σ (uniform in
/// `blur_sigma_px`, separable Gaussian, radius ⌈3σ⌉, edges clamped); per value Gaussian noise
/// of variance `shot_noise` · v + `read_noise`², clamped to 0..1.
/// `depth`: the rendered depth (metres, 0 = nothing) and instance ids, for defocus.
pub(crate) fn apply_rgb(
    spec: &RgbNoiseSpec,
    luts: &ColorLuts,
    w: usize,
    h: usize,
    rgb: &mut [u8],
    depth: Option<(&[f32], &[u16])>,
    rng: &mut ChaCha8Rng,
) {
    let stops = uniform(rng, spec.exposure_stops);
    let sigma = uniform(rng, spec.blur_sigma_px);
    let gain = 2f64.powf(stops) as f32;
    // Drawn only when asked for, so other specs keep their noise.
    let wb = if spec.white_balance > 0.0 {
        let d = spec.white_balance;
        [
            rng.gen_range(1.0 - d..=1.0 + d) as f32,
            1.0,
            rng.gen_range(1.0 - d..=1.0 + d) as f32,
        ]
    } else {
        [1.0; 3]
    };
    let vig = if spec.vignetting[1] > 0.0 {
        uniform(rng, spec.vignetting) as f32
    } else {
        0.0
    };
    let mut lin: Vec<f32> = rgb
        .iter()
        .map(|&b| luts.to_linear[b as usize] * gain)
        .collect();
    if wb != [1.0; 3] || vig > 0.0 {
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        let r2_max = cx * cx + cy * cy;
        for (i, px) in lin.chunks_exact_mut(3).enumerate() {
            let (dx, dy) = ((i % w) as f32 + 0.5 - cx, (i / w) as f32 + 0.5 - cy);
            let v = 1.0 - vig * (dx * dx + dy * dy) / r2_max;
            for (c, g) in px.iter_mut().zip(wb) {
                *c *= g * v;
            }
        }
    }
    // Drawn only when asked for, so other specs keep their noise.
    if spec.defocus_px[1] > 0.0 {
        let c_inf = uniform(rng, spec.defocus_px) as f32;
        if let Some((d, inst)) = depth {
            defocus(&mut lin, w, h, d, inst, c_inf);
        }
    }
    if spec.motion_blur_px[1] > 0.0 {
        let len = uniform(rng, spec.motion_blur_px) as f32;
        let angle = rng.gen_range(0.0..std::f32::consts::PI);
        motion_blur(&mut lin, w, h, len, angle);
    }
    if sigma > 0.05 {
        blur(&mut lin, w, h, sigma as f32);
    }
    let shot = spec.shot_noise as f32;
    let read2 = (spec.read_noise * spec.read_noise) as f32;
    for (v, out) in lin.iter().zip(rgb.iter_mut()) {
        let v = v.clamp(0.0, 1.0);
        let n = approx_normal(rng.next_u64());
        let noisy = v + (shot * v + read2).sqrt() * n;
        *out = luts.srgb_at(srgb_index(noisy * TO_SRGB_MAX as f32));
    }
    // Last, as a camera's encoder does: JPEG at a quality drawn per frame.
    if spec.jpeg_quality[1] > 0.0 {
        let q = uniform(rng, spec.jpeg_quality).round().clamp(1.0, 100.0) as u8;
        jpeg_round_trip(rgb, w, h, q);
    }
}

/// Encodes `rgb` (sRGB bytes) as a baseline JPEG of quality `q` (1..100, 4:2:0 chroma as
/// `image`'s encoder writes it) and decodes it back in place: the blocks, ringing and colour
/// bleeding of a compressed camera stream. Left as it is if either step fails (it cannot for
/// a well-formed buffer).
fn jpeg_round_trip(rgb: &mut [u8], w: usize, h: usize, q: u8) {
    use image::codecs::jpeg::{JpegDecoder, JpegEncoder};
    use image::ImageDecoder;
    let mut bytes = Vec::new();
    let encoded = JpegEncoder::new_with_quality(&mut bytes, q).encode(
        rgb,
        w as u32,
        h as u32,
        image::ExtendedColorType::Rgb8,
    );
    if encoded.is_err() {
        return;
    }
    let Ok(dec) = JpegDecoder::new(std::io::Cursor::new(&bytes)) else {
        return;
    };
    if dec.dimensions() != (w as u32, h as u32) || dec.color_type() != image::ColorType::Rgb8 {
        return;
    }
    let mut out = vec![0u8; rgb.len()];
    if dec.read_image(&mut out).is_ok() {
        rgb.copy_from_slice(&out);
    }
}

fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        rng.gen_range(lo..=hi)
    } else {
        lo
    }
}

/// A standard normal approximated by the sum of four uniforms (Irwin-Hall, rescaled to unit
/// variance, tails cut at ±3.46σ) from one 64-bit draw: per-value noise on 0.9 M values per
/// frame must be cheap, and image noise needs no far tails.
#[inline]
fn approx_normal(bits: u64) -> f32 {
    let s = (bits & 0xffff) + ((bits >> 16) & 0xffff) + ((bits >> 32) & 0xffff) + (bits >> 48);
    // Each part is uniform on 0..65535 (mean 32767.5, variance ~ 65536² / 12).
    const MEAN: f32 = 4.0 * 32767.5;
    const SCALE: f32 = 1.732_050_8 / 65536.0; // √3 / 65536: unit variance for 4 parts
    (s as f32 - MEAN) * SCALE
}

/// Defocus: each pixel becomes the mean of the square of half-side round(c(z)) around it
/// (a box standing in for the lens's disk; from a summed-area table, so any radius costs the
/// same), c(z) = `c_inf` · |1 − z_f / z| with z_f the median depth of the object pixels
/// (`inst` > 0; of all pixels with depth when no object shows) and c = `c_inf` where there is
/// no depth (the far background). A gather: a blurred foreground does not spill over a sharp
/// background (as a real lens's would, slightly).
fn defocus(img: &mut [f32], w: usize, h: usize, depth: &[f32], inst: &[u16], c_inf: f32) {
    if c_inf < 0.5 || depth.len() != w * h {
        return;
    }
    let mut zs: Vec<f32> = depth
        .iter()
        .zip(inst)
        .filter(|(z, i)| **z > 0.0 && **i > 0)
        .map(|(z, _)| *z)
        .collect();
    if zs.is_empty() {
        zs = depth.iter().copied().filter(|z| *z > 0.0).collect();
    }
    if zs.is_empty() {
        return;
    }
    let mid = zs.len() / 2;
    let zf = *zs.select_nth_unstable_by(mid, f32::total_cmp).1;
    // Summed-area table with a zero row and column in front: (w + 1) x (h + 1) x 3, f64.
    let sw = w + 1;
    let mut sat = vec![0f64; sw * (h + 1) * 3];
    for y in 0..h {
        let mut row = [0f64; 3];
        for x in 0..w {
            for c in 0..3 {
                row[c] += f64::from(img[(y * w + x) * 3 + c]);
                sat[((y + 1) * sw + x + 1) * 3 + c] = sat[(y * sw + x + 1) * 3 + c] + row[c];
            }
        }
    }
    for y in 0..h {
        for x in 0..w {
            let z = depth[y * w + x];
            let c = if z > 0.0 {
                c_inf * (1.0 - zf / z).abs()
            } else {
                c_inf
            };
            let r = c.round() as usize;
            if r == 0 {
                continue;
            }
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
            let n = ((x1 - x0) * (y1 - y0)) as f64;
            for ch in 0..3 {
                let at = |yy: usize, xx: usize| sat[(yy * sw + xx) * 3 + ch];
                let sum = at(y1, x1) - at(y0, x1) - at(y1, x0) + at(y0, x0);
                img[(y * w + x) * 3 + ch] = (sum / n) as f32;
            }
        }
    }
}

/// Motion blur: each pixel becomes the mean of ⌈len⌉ + 1 samples (nearest pixel, edges
/// clamped) evenly spaced along a segment of `len` pixels centred on it at `angle` radians.
fn motion_blur(img: &mut [f32], w: usize, h: usize, len: f32, angle: f32) {
    if len < 0.5 {
        return;
    }
    let n = len.ceil() as usize + 1;
    let (dx, dy) = (angle.cos() * len, angle.sin() * len);
    let offsets: Vec<(isize, isize)> = (0..n)
        .map(|i| {
            let t = i as f32 / (n - 1) as f32 - 0.5;
            ((t * dx).round() as isize, (t * dy).round() as isize)
        })
        .collect();
    let src = img.to_vec();
    let (wi, hi) = (w as isize, h as isize);
    for y in 0..hi {
        for x in 0..wi {
            let mut acc = [0f32; 3];
            for &(ox, oy) in &offsets {
                let s = (((y + oy).clamp(0, hi - 1) * wi + (x + ox).clamp(0, wi - 1)) * 3) as usize;
                for c in 0..3 {
                    acc[c] += src[s + c];
                }
            }
            let o = ((y * wi + x) * 3) as usize;
            for c in 0..3 {
                img[o + c] = acc[c] / n as f32;
            }
        }
    }
}

/// Separable Gaussian blur of an interleaved RGB float image, edges clamped.
fn blur(img: &mut [f32], w: usize, h: usize, sigma: f32) {
    let r = (3.0 * sigma).ceil() as isize;
    let mut k: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    let mut tmp = vec![0.0f32; img.len()];
    let (wi, hi) = (w as isize, h as isize);
    for y in 0..h {
        for x in 0..wi {
            let mut acc = [0.0f32; 3];
            for (j, kv) in k.iter().enumerate() {
                let sx = (x + j as isize - r).clamp(0, wi - 1) as usize;
                let s = (y * w + sx) * 3;
                for c in 0..3 {
                    acc[c] += kv * img[s + c];
                }
            }
            tmp[(y * w + x as usize) * 3..][..3].copy_from_slice(&acc);
        }
    }
    for y in 0..hi {
        for x in 0..w {
            let mut acc = [0.0f32; 3];
            for (j, kv) in k.iter().enumerate() {
                let sy = (y + j as isize - r).clamp(0, hi - 1) as usize;
                let s = (sy * w + x) * 3;
                for c in 0..3 {
                    acc[c] += kv * tmp[s + c];
                }
            }
            img[(y as usize * w + x) * 3..][..3].copy_from_slice(&acc);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// White balance scales red and blue against green; vignetting darkens the corners and
    /// not the centre; with both at 0 (the defaults) nothing is drawn or changed.
    #[test]
    fn white_balance_and_vignetting() {
        let luts = ColorLuts::new();
        let (w, h) = (32usize, 24usize);
        let quiet = RgbNoiseSpec {
            enabled: true,
            exposure_stops: [0.0, 0.0],
            blur_sigma_px: [0.0, 0.0],
            shot_noise: 0.0,
            read_noise: 0.0,
            white_balance: 0.0,
            vignetting: [0.0, 0.0],
            defocus_px: [0.0, 0.0],
            motion_blur_px: [0.0, 0.0],
            jpeg_quality: [0.0, 0.0],
        };
        let grey = vec![128u8; w * h * 3];
        let run = |spec: &RgbNoiseSpec, seed: u64| {
            let mut img = grey.clone();
            let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
            apply_rgb(spec, &luts, w, h, &mut img, None, &mut rng);
            img
        };
        assert_eq!(run(&quiet, 1), grey);
        let wb = RgbNoiseSpec {
            white_balance: 0.2,
            ..quiet.clone()
        };
        let mut moved = false;
        for seed in 0..8 {
            let img = run(&wb, seed);
            assert!(
                img.chunks_exact(3).all(|p| p[1] == 128),
                "green is the reference"
            );
            let (r, b) = (img[0], img[2]);
            assert!(
                img.chunks_exact(3).all(|p| p[0] == r && p[2] == b),
                "one gain per frame"
            );
            moved |= r != 128 || b != 128;
        }
        assert!(moved);
        let vig = RgbNoiseSpec {
            vignetting: [0.5, 0.5],
            ..quiet
        };
        let img = run(&vig, 2);
        let at = |x: usize, y: usize| img[(y * w + x) * 3];
        assert!(at(w / 2, h / 2) >= 127, "the centre keeps its value");
        assert!(
            at(0, 0) < 110 && at(w - 1, h - 1) < 110,
            "the corners darken: {}",
            at(0, 0)
        );
    }

    #[test]
    fn approx_normal_has_unit_variance() {
        let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
        let n = 200_000;
        let xs: Vec<f64> = (0..n)
            .map(|_| f64::from(approx_normal(rng.next_u64())))
            .collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.02, "{var}");
    }

    #[test]
    fn blur_keeps_a_constant_image_and_spreads_a_dot() {
        let (w, h) = (9, 7);
        let mut img = vec![0.5f32; w * h * 3];
        blur(&mut img, w, h, 1.0);
        assert!(img.iter().all(|v| (v - 0.5).abs() < 1e-5));
        let mut dot = vec![0.0f32; w * h * 3];
        dot[(3 * w + 4) * 3] = 1.0;
        blur(&mut dot, w, h, 1.0);
        let total: f32 = dot.iter().step_by(3).sum();
        assert!((total - 1.0).abs() < 1e-4);
        assert!(dot[(3 * w + 4) * 3] < 0.2 && dot[(3 * w + 5) * 3] > 0.05);
    }

    /// Defocus leaves the focused object sharp and blurs what lies far behind it; motion blur
    /// smears a dot into a streak along its direction, keeping its energy.
    #[test]
    fn jpeg_compression_blocks_a_sharp_edge_and_keeps_a_flat_image() {
        let (w, h) = (48usize, 32usize);
        let flat = vec![120u8; w * h * 3];
        let mut f = flat.clone();
        jpeg_round_trip(&mut f, w, h, 50);
        assert!(
            f.iter().zip(&flat).all(|(a, b)| a.abs_diff(*b) <= 1),
            "flat stays flat"
        );
        // A hard red/blue edge: low quality rings around it and bleeds the colours, and
        // more so at quality 10 than at 90.
        let edge: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                if i % w < 21 {
                    [220, 30, 30]
                } else {
                    [30, 30, 220]
                }
            })
            .collect();
        let err = |q: u8| {
            let mut e = edge.clone();
            jpeg_round_trip(&mut e, w, h, q);
            e.iter()
                .zip(&edge)
                .map(|(a, b)| u64::from(a.abs_diff(*b)))
                .sum::<u64>()
        };
        let (low, high) = (err(10), err(90));
        assert!(
            low > 2 * high && high > 0,
            "quality 10: {low}, quality 90: {high}"
        );
    }

    #[test]
    fn defocus_by_depth_and_motion_streaks() {
        let (w, h) = (40usize, 20usize);
        // A checkerboard: an object (instance 1) at 0.5 m on the left half, a wall at 5 m.
        let mut img = vec![0f32; w * h * 3];
        let mut depth = vec![0f32; w * h];
        let mut inst = vec![0u16; w * h];
        for y in 0..h {
            for x in 0..w {
                let v = ((x + y) % 2) as f32;
                img[(y * w + x) * 3..][..3].copy_from_slice(&[v; 3]);
                depth[y * w + x] = if x < w / 2 { 0.5 } else { 5.0 };
                inst[y * w + x] = u16::from(x < w / 2);
            }
        }
        let orig = img.clone();
        defocus(&mut img, w, h, &depth, &inst, 4.0);
        let contrast =
            |im: &[f32], x: usize| (im[(10 * w + x) * 3] - im[(10 * w + x + 1) * 3]).abs();
        assert_eq!(contrast(&img, 5), contrast(&orig, 5), "in focus: untouched");
        // At 5 m: c = 4 · |1 − 0.5 / 5| = 3.6 → a 9x9 box over a checkerboard: contrast ~1/81.
        assert!(
            contrast(&img, 30) < 0.05,
            "far: blurred ({})",
            contrast(&img, 30)
        );
        let mut dot = vec![0f32; w * h * 3];
        dot[(10 * w + 20) * 3] = 1.0;
        motion_blur(&mut dot, w, h, 8.0, 0.0);
        let row: Vec<f32> = (0..w).map(|x| dot[(10 * w + x) * 3]).collect();
        let lit = row.iter().filter(|v| **v > 0.0).count();
        assert_eq!(lit, 9, "a horizontal streak of 9 samples: {row:?}");
        let total: f32 = dot.iter().sum();
        assert!((total - 1.0).abs() < 1e-5, "energy kept: {total}");
        assert!(
            (0..h).all(|y| y == 10 || dot[(y * w + 20) * 3] == 0.0),
            "horizontal only"
        );
    }
}
