//! Structured-light depth, the Kinect v1 / PrimeSense / Asus Xtion family: a projector
//! beside the depth camera; depth from the disparity of the projected pattern. See
//! `StructuredLightSpec` for the parameters and docs/sensors.md for the method and the fit.
//!
//! Per-pixel random numbers come from a counter-based hash of (frame seed, pixel, use), so a
//! pixel's fate depends on nothing but the seed and its index, and the model costs a few
//! nanoseconds per pixel (the render benchmark's `structured_light` line).

use synthgen_core::depth_features::{
    discontinuities, edge_distance, mix64, smooth_uniform_field, viewpoint_shadows,
};
use synthgen_core::scene::StructuredLightSpec;
use synthgen_core::Intrinsics;

/// 64 random bits for pixel `i`, use `stream` (0..8), frame `seed`.
#[inline]
fn bits(seed: u64, i: usize, stream: u64) -> u64 {
    mix64(seed.wrapping_add((i as u64 * 8 + stream).wrapping_mul(0x9e37_79b9_7f4a_7c15)))
}

/// Two uniforms in [0, 1) from 64 bits.
#[inline]
fn uniforms(b: u64) -> (f64, f64) {
    const S: f64 = 1.0 / 4_294_967_296.0;
    ((b >> 32) as f64 * S, (b & 0xffff_ffff) as f64 * S)
}

/// A standard normal draw from 64 bits: the sum of four 16-bit uniforms, centred and scaled
/// (Irwin–Hall; tails end at ±3.46 σ, which depth noise never needs).
#[inline]
fn normal_draw(b: u64) -> f64 {
    let s: u64 = (b & 0xffff) + ((b >> 16) & 0xffff) + ((b >> 32) & 0xffff) + (b >> 48);
    ((s as f64 + 2.0) / 65_536.0 - 2.0) * 3f64.sqrt()
}

/// Applies the structured-light model to `depth` (metres, row-major `k.width` x `k.height`,
/// 0 = no surface) in place. `rgb` is the rendered colour (brightness-dependent holes; any
/// other length counts as mid-grey) and `seed` the frame's sensor seed.
pub fn apply_structured_light(
    spec: &StructuredLightSpec,
    k: &Intrinsics,
    rgb: &[u8],
    depth: &mut [f32],
    seed: u64,
) {
    let (w, h) = (k.width as usize, k.height as usize);
    let n = w * h;
    // Wider rows than the camera limit (`Intrinsics::validate` refuses them) never get here.
    if depth.len() != n || n == 0 || w > MAX_ROW {
        return;
    }
    let clean = depth.to_vec();
    let rel = spec.edge_jump_rel;
    let edges = discontinuities(&clean, w, h, rel as f32);
    let reach = (spec.edge_width_px * 6.0).ceil().clamp(2.0, 64.0) as u8;
    let dist = edge_distance(&edges, w, h, reach);
    let shadow = spec.shadow.then(|| {
        let offsets = [k.fx * spec.baseline_m, k.fx * spec.second_view_m];
        viewpoint_shadows(&clean, w, h, &offsets, false)
    });

    // Fattening along rows (the direction of the disparity search): from every edge pixel of
    // a closer surface, the pixels beyond it that lie farther (or empty) read the closer
    // depth, the first ⌊F⌋ for sure and the next with probability frac(F).
    let mut src = clean.clone();
    let mut fattened = vec![false; n];
    if spec.fattening_px > 0.0 {
        let steps = spec.fattening_px.ceil() as usize;
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let z = clean[i];
                if !edges[i] || z <= 0.0 {
                    continue;
                }
                let (u_left, u_right) = uniforms(bits(seed, i, 2));
                for (dir, u) in [(-1isize, u_left), (1, u_right)] {
                    for s in 1..=steps {
                        let nx = x as isize + dir * s as isize;
                        if nx < 0 || nx >= w as isize {
                            break;
                        }
                        let j = y * w + nx as usize;
                        let zj = clean[j];
                        if zj > 0.0 && zj <= z * (1.0 + rel as f32) {
                            break;
                        }
                        let p = (spec.fattening_px - (s - 1) as f64).min(1.0);
                        if u >= p {
                            break;
                        }
                        if src[j] <= 0.0 || src[j] > z {
                            src[j] = z;
                            fattened[j] = true;
                        }
                    }
                }
            }
        }
    }

    // Tables instead of exp() and acos() per pixel: the keep probabilities by edge distance,
    // by cos² θ (1/1024 steps) and by 8-bit luma; 256 entries where a u8 indexes them, so
    // the lookups need no bounds checks.
    let mut keep_edge = [1f32; 256];
    let mut edge_mix = [0f32; 256];
    for d in 0..usize::from(reach) {
        keep_edge[d] = (1.0 - spec.edge_dropout * (-(d as f64) / spec.edge_width_px).exp()) as f32;
        edge_mix[d] = spec.mix_probability(d as f64) as f32;
    }
    // At the cap (six decay lengths away, or more) edges no longer matter.
    let far_px = usize::from(reach);
    keep_edge[far_px] =
        (1.0 - spec.edge_dropout * (-(far_px as f64) / spec.edge_width_px).exp()) as f32;
    let mut keep_graze = [0f32; COS2_LEN];
    for (i, v) in keep_graze.iter_mut().enumerate() {
        let t = (i as f64 / f64::from(COS2_STEPS))
            .sqrt()
            .acos()
            .to_degrees();
        *v = (1.0 - 1.0 / (1.0 + (-(t - spec.grazing_deg) / spec.grazing_width_deg).exp())) as f32;
    }
    let mut keep_luma = [0f32; 256];
    for (l, v) in keep_luma.iter_mut().enumerate() {
        *v = spec.keep_by_brightness(l as f64 / 255.0) as f32;
    }
    let has_rgb = rgb.len() == n * 3;
    let grey = vec![128u8; 3 * w];
    let noise = Noise::new(spec, k);
    let (ifx, ify) = (1.0 / k.fx as f32, 1.0 / k.fy as f32);
    let rxs: Vec<f32> = (0..w).map(|x| (x as f32 - k.cx as f32) * ifx).collect();
    let zeros = vec![0f32; w];
    let no_shadow = vec![false; w];
    let tables = RandomTables::get();
    // The hole and mixing decisions: one smooth field (holes where it is low, mixing where it
    // is high), so holes come in blobs as a real sensor's do.
    let field = smooth_uniform_field(w, h, spec.hole_size_px, mix64(seed ^ 0x686f_6c65));
    let mut cos2 = vec![1f32; w];
    let mut keep = vec![0f32; w];
    let mut out = vec![0f32; w];

    for y in 0..h {
        let row = y * w..(y + 1) * w;
        let ry = (y as f32 - k.cy as f32) * ify;
        let fat_row = &fattened[row.clone()];
        let dist_row = &dist[row.clone()];
        // cos² θ from the clean depth (fattened pixels face the camera).
        cos2_row(
            &clean[row.clone()],
            if y > 0 {
                &clean[row.start - w..row.start]
            } else {
                &zeros
            },
            if y + 1 < h {
                &clean[row.end..row.end + w]
            } else {
                &zeros
            },
            rel as f32,
            &rxs,
            ry,
            ifx,
            ify,
            &mut cos2,
        );
        // Keep probabilities: brightness × edge distance × incidence (table lookups), 0 in
        // the projector's shadow unless the pixel took a closer surface's depth.
        let rgb_row = if has_rgb {
            &rgb[3 * row.start..3 * row.end]
        } else {
            &grey[..]
        };
        let shadow_row = shadow.as_ref().map_or(&no_shadow[..], |s| &s[row.clone()]);
        for (((((kp, c), px), &d), &f), &sh) in keep
            .iter_mut()
            .zip(cos2.iter_mut())
            .zip(rgb_row.chunks_exact(3))
            .zip(dist_row)
            .zip(fat_row)
            .zip(shadow_row)
        {
            if f {
                *c = 1.0;
            }
            let kg = keep_graze[((*c * COS2_STEPS + 0.5) as usize).min(COS2_LEN - 1)];
            let kl = keep_luma[usize::from(luma8([px[0], px[1], px[2]]))];
            let k = kl * keep_edge[usize::from(d)] * kg;
            *kp = if sh & !f { 0.0 } else { k };
        }
        let normals = tables.row(seed, y, w);
        let u_hole = &field[row.clone()];
        noise.row(&src[row.clone()], &cos2, &keep, u_hole, normals, &mut out);
        // Near edges some readings come from the farthest surface around (rare: a fix-up).
        for x in 0..w {
            let d = usize::from(dist_row[x]);
            if d >= far_px {
                continue;
            }
            if out[x] > 0.0 && !fat_row[x] && 1.0 - u_hole[x] < edge_mix[d] {
                let far = farthest_around(&clean, w, h, x, y, d + 1);
                out[x] = if far > 0.0 {
                    noise.reading(far as f32, cos2[x], normals[x])
                } else {
                    0.0
                };
            }
        }
        depth[row].copy_from_slice(&out);
    }
    if spec.shift_px != 0.0 {
        // The hole field again: neighbours move together (a hole's own choice is moot).
        shift_rows(depth, w, h, spec.shift_px, &field);
    }
}

/// cos² θ steps of the keep-by-incidence table.
const COS2_STEPS: f32 = 1024.0;
const COS2_LEN: usize = 1025;

/// Per-pixel noise: a fixed table of normals (drawn once from a fixed seed), read from a
/// per-row offset that the frame's seed picks. A row reads contiguous
/// slices, which lets the per-pixel arithmetic vectorize; 2^20 entries make repeats within a
/// frame rare and harmless (noise, not structure).
struct RandomTables {
    normal: Vec<f32>,
}

const TABLE_LEN: usize = 1 << 20;

impl RandomTables {
    fn get() -> &'static RandomTables {
        static TABLES: std::sync::OnceLock<RandomTables> = std::sync::OnceLock::new();
        TABLES.get_or_init(|| {
            let normal = (0..TABLE_LEN + MAX_ROW)
                .map(|i| normal_draw(bits(0x5eed_5eed, i, 6)) as f32)
                .collect();
            RandomTables { normal }
        })
    }

    /// The normals for row `y` (`w` ≤ [`MAX_ROW`] wide).
    fn row(&self, seed: u64, y: usize, w: usize) -> &[f32] {
        let at = (bits(seed, y, 2) % TABLE_LEN as u64) as usize;
        &self.normal[at..at + w]
    }
}

/// Widest image row the tables serve: the widest camera `Intrinsics::validate` accepts.
pub const MAX_ROW: usize = 16_384;

/// The noise part of the model: disparity noise (matching noise and the lateral shift
/// along the surface's slope), disparity quantization, bias, output unit and range.
struct Noise {
    /// f |b|, px·m.
    fb: f32,
    sd2: f32,
    /// (f |b| σ_lat / fx)²: the lateral term's variance in disparity is this × tan² θ / z².
    lat2: f32,
    sub: f32,
    inv_sub: f32,
    bias: f32,
    unit: f32,
    inv_unit: f32,
    lo: f32,
    hi: f32,
    /// Nothing to do: no noise, no quantization, no bias, no unit.
    identity: bool,
}

impl Noise {
    fn new(spec: &StructuredLightSpec, k: &Intrinsics) -> Noise {
        let fb = spec.focal_baseline(k.fx);
        let lat = fb * spec.lateral_sigma_px / k.fx;
        let inv = |v: f64| if v > 0.0 { (1.0 / v) as f32 } else { 0.0 };
        Noise {
            fb: fb as f32,
            sd2: (spec.disparity_sigma_px * spec.disparity_sigma_px) as f32,
            lat2: (lat * lat) as f32,
            sub: spec.subpixel as f32,
            inv_sub: inv(spec.subpixel),
            bias: spec.bias_m as f32,
            unit: spec.depth_unit_m as f32,
            inv_unit: inv(spec.depth_unit_m),
            lo: spec.range_m[0] as f32,
            hi: spec.range_m[1] as f32,
            identity: spec.disparity_sigma_px == 0.0
                && spec.lateral_sigma_px == 0.0
                && spec.subpixel == 0.0
                && spec.bias_m == 0.0
                && spec.depth_unit_m == 0.0,
        }
    }

    /// One reading of a surface at `z` (> 0) seen at cos² θ = `c2`, with normal draw `n`.
    fn reading(&self, z: f32, c2: f32, n: f32) -> f32 {
        match (self.identity, self.inv_sub > 0.0, self.inv_unit > 0.0) {
            (true, _, _) => self.in_range(z),
            (false, false, false) => self.noisy::<false, false>(z, c2, n),
            (false, true, false) => self.noisy::<true, false>(z, c2, n),
            (false, false, true) => self.noisy::<false, true>(z, c2, n),
            (false, true, true) => self.noisy::<true, true>(z, c2, n),
        }
    }

    #[inline(always)]
    fn in_range(&self, z: f32) -> f32 {
        // `&`, not `&&`: no branch, so the row loops vectorize.
        if (z >= self.lo) & (z <= self.hi) {
            z
        } else {
            0.0
        }
    }

    /// The reading with noise, quantization (`Q`) and the output unit (`U`).
    #[inline(always)]
    fn noisy<const Q: bool, const U: bool>(&self, z: f32, c2: f32, n: f32) -> f32 {
        let inv = 1.0 / z;
        let tan2 = 1.0 / c2.max(1e-4) - 1.0;
        let sigma = (self.sd2 + self.lat2 * tan2 * inv * inv).sqrt();
        let mut disp = self.fb * inv + sigma * n;
        if Q {
            disp = round32(disp * self.inv_sub) * self.sub;
        }
        let ok = disp > 0.0;
        let mut zn = self.fb / disp.max(1e-6) + self.bias;
        if U {
            zn = round32(zn * self.inv_unit) * self.unit;
        }
        let zn = self.in_range(zn);
        if ok {
            zn
        } else {
            0.0
        }
    }

    /// A row of readings: 0 where `z` is empty or the hole uniform is not below `keep`.
    #[inline(never)]
    fn row(&self, z: &[f32], c2: &[f32], keep: &[f32], u: &[f32], n: &[f32], out: &mut [f32]) {
        match (self.identity, self.inv_sub > 0.0, self.inv_unit > 0.0) {
            (true, _, _) => self.row_with(z, c2, keep, u, n, out, |z, _, _| self.in_range(z)),
            (false, false, false) => self.row_with(z, c2, keep, u, n, out, |z, c, v| {
                self.noisy::<false, false>(z, c, v)
            }),
            (false, true, false) => self.row_with(z, c2, keep, u, n, out, |z, c, v| {
                self.noisy::<true, false>(z, c, v)
            }),
            (false, false, true) => self.row_with(z, c2, keep, u, n, out, |z, c, v| {
                self.noisy::<false, true>(z, c, v)
            }),
            (false, true, true) => self.row_with(z, c2, keep, u, n, out, |z, c, v| {
                self.noisy::<true, true>(z, c, v)
            }),
        }
    }

    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn row_with(
        &self,
        z: &[f32],
        c2: &[f32],
        keep: &[f32],
        u: &[f32],
        n: &[f32],
        out: &mut [f32],
        f: impl Fn(f32, f32, f32) -> f32,
    ) {
        let len = out.len();
        let (z, c2, keep, u, n) = (&z[..len], &c2[..len], &keep[..len], &u[..len], &n[..len]);
        for x in 0..len {
            let zi = z[x];
            let valid = (zi > 0.0) & (u[x] < keep[x]);
            let r = f(if zi > 0.0 { zi } else { 1.0 }, c2[x], n[x]);
            out[x] = if valid { r } else { 0.0 };
        }
    }
}

/// Rounds to the nearest integer (ties to even) for |v| < 2^22 by adding and removing
/// 1.5 · 2^23: two additions, where `f32::round` is a library call without SSE4.1 and an
/// `as` conversion checks for saturation.
#[inline(always)]
fn round32(v: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0;
    (v + MAGIC) - MAGIC
}

/// cos² θ of a row of pixels from the depth's derivatives (see
/// `depth_features::incidence_cos`, which this squares): neighbours on the same surface
/// (within `rel`), central differences where both are, else one-sided, else 0; with the ray
/// (rx, ry, 1). Empty pixels get 1. Branch-free, so it vectorizes.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn cos2_row(
    row: &[f32],
    up: &[f32],
    down: &[f32],
    rel: f32,
    rxs: &[f32],
    ry: f32,
    ifx: f32,
    ify: f32,
    out: &mut [f32],
) {
    let w = row.len();
    let weight = |n: f32, z: f32| -> f32 {
        if n > 0.0 && (n - z).abs() <= rel * z {
            1.0
        } else {
            0.0
        }
    };
    let c2 = |z: f32, l: f32, r: f32, u: f32, d: f32, rx: f32| -> f32 {
        let (wl, wr, wu, wd) = (weight(l, z), weight(r, z), weight(u, z), weight(d, z));
        // One-sided where one neighbour counts, central where both: divide by their count.
        let zu = (wr * (r - z) + wl * (z - l)) / (wl + wr).max(1.0);
        let zv = (wd * (d - z) + wu * (z - u)) / (wu + wd).max(1.0);
        let a = z * zu * ify;
        let b = z * zv * ifx;
        let c = z * z * ifx * ify;
        let nz = a * rx + b * ry + c;
        let nn2 = a * a + b * b + nz * nz;
        let rn2 = rx * rx + ry * ry + 1.0;
        let v = c * c / (nn2 * rn2).max(1e-30);
        if z > 0.0 {
            v.min(1.0)
        } else {
            1.0
        }
    };
    if w == 0 {
        return;
    }
    if w == 1 {
        out[0] = c2(row[0], 0.0, 0.0, up[0], down[0], rxs[0]);
        return;
    }
    out[0] = c2(row[0], 0.0, row[1], up[0], down[0], rxs[0]);
    out[w - 1] = c2(
        row[w - 1],
        row[w - 2],
        0.0,
        up[w - 1],
        down[w - 1],
        rxs[w - 1],
    );
    let (l, mid, r) = (&row[..w - 2], &row[1..w - 1], &row[2..]);
    let (u, d, rx) = (&up[1..w - 1], &down[1..w - 1], &rxs[1..w - 1]);
    for (x, o) in out[1..w - 1].iter_mut().enumerate() {
        *o = c2(mid[x], l[x], r[x], u[x], d[x], rx[x]);
    }
}

/// Displaces every row by `shift` pixels (dithered: a pixel reads column x − shift rounded
/// down or up, up where the smooth `dither` field is below the fraction, so neighbours mostly
/// move together); what comes from outside the image is 0.
fn shift_rows(depth: &mut [f32], w: usize, h: usize, shift: f64, dither: &[f32]) {
    let src = depth.to_vec();
    let base = (-shift).floor();
    let frac = -shift - base;
    let base = base as isize;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let sx = x as isize + base + isize::from(f64::from(dither[i]) < frac);
            depth[i] = if sx >= 0 && (sx as usize) < w {
                src[y * w + sx as usize]
            } else {
                0.0
            };
        }
    }
}

/// 8-bit luma of an sRGB pixel: Rec. 709 weights, as `depth_features::luminance` × 255.
#[inline]
fn luma8(p: [u8; 3]) -> u8 {
    ((u32::from(p[0]) * 13933 + u32::from(p[1]) * 46871 + u32::from(p[2]) * 4732 + 32768) >> 16)
        as u8
}

/// The farthest depth within `r` pixels (a square window) of (x, y); 0 when any pixel there
/// is empty (the far side is nothing).
fn farthest_around(d: &[f32], w: usize, h: usize, x: usize, y: usize, r: usize) -> f64 {
    let mut far = 0f32;
    for ny in y.saturating_sub(r)..=(y + r).min(h - 1) {
        for nx in x.saturating_sub(r)..=(x + r).min(w - 1) {
            let z = d[ny * w + nx];
            if z <= 0.0 {
                return 0.0;
            }
            far = far.max(z);
        }
    }
    f64::from(far)
}

#[cfg(test)]
#[path = "structured_light_tests.rs"]
mod tests;
