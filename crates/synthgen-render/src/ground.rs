//! The ground plane: depth by exact ray-plane intersection per pixel centre (no triangles,
//! so no near-plane clipping is needed), and a cheap procedural tile texture.
//!
//! The ground covers most of a typical frame, so a row is drawn in few branch-free passes
//! the compiler vectorizes (depth, depth test and tile index in one; then colour per chunk of
//! pixels), with only the table lookups (tile pattern, sRGB) left scalar.

use synthgen_core::glam::Vec3;
use synthgen_core::sample::{GroundInstance, WallInstance};
use synthgen_core::Pose;

use crate::bits::{floor_low_bits, select};
use crate::color::{srgb_index32, srgb_to_linear_f32, ColorLuts, TO_SRGB_MAX};
use crate::raster::Projection;
use crate::shade::{Light, ShadeParams};
use crate::surface::TexMap;

/// Side of the fine texture tiles, metres; coarse tiles are 4 x 4 fine ones (8 cm).
const FINE_TILE_M: f32 = 0.02;
/// The tile table covers TILES x TILES fine tiles (5.12 m, more than a default 3 m plane)
/// and repeats beyond.
const TILES_LOG2: u32 = 8;
const TILES: usize = 1 << TILES_LOG2;
const TILE_MASK: i32 = TILES as i32 - 1;

/// The tile pattern, built once per renderer: per fine tile 0.7 x its coarse tile's random
/// value + 0.3 x its own, quantized to a byte.
#[derive(Clone)]
pub(crate) struct TileTables {
    pattern: Vec<u8>,
}

impl TileTables {
    pub fn new() -> TileTables {
        let unit = |h: u32| (h >> 8) as f32 / 16_777_216.0;
        let pattern = (0..TILES * TILES)
            .map(|k| {
                let (i, j) = ((k % TILES) as u32, (k / TILES) as u32);
                let coarse = unit(hash32((i >> 2) | ((j >> 2) << 16) ^ 0x51ed_270b));
                let fine = unit(hash32(i | (j << 16) ^ 0x2545_f491));
                ((0.7 * coarse + 0.3 * fine) * 255.0 + 0.5) as u8
            })
            .collect();
        TileTables { pattern }
    }
}

/// A textured plane rectangle in the camera frame: the ground, or a wall.
pub(crate) struct Ground<'a> {
    origin: Vec3,
    e1: Vec3,
    e2: Vec3,
    normal: Vec3,
    /// normal . origin
    num: f32,
    /// Half sides along e1 and e2.
    half_u: f32,
    half_v: f32,
    albedo_linear: [f32; 3],
    strength: f32,
    /// Per-frame offset into the tile table (x, y), so frames differ.
    offsets: [i32; 2],
    /// An image texture instead of the procedural tiles.
    texture: Option<TexMap<'a>>,
}

impl<'a> Ground<'a> {
    pub fn new(g: &GroundInstance, texture: Option<TexMap<'a>>) -> Ground<'a> {
        let s = g.texture_seed;
        let half = (g.size_m * 0.5) as f32;
        Self::plane(
            &g.cam_from_plane,
            [half, half],
            g.color,
            g.texture_strength,
            [
                (s as i32) & TILE_MASK,
                ((s >> TILES_LOG2) as i32) & TILE_MASK,
            ],
            texture,
        )
    }

    /// A wall: plain colour, or its image texture.
    pub fn wall(w: &WallInstance, texture: Option<TexMap<'a>>) -> Ground<'a> {
        Self::plane(
            &w.cam_from_wall,
            [(w.width_m * 0.5) as f32, (w.height_m * 0.5) as f32],
            w.color,
            0.0,
            [0, 0],
            texture,
        )
    }

    fn plane(
        cam_from_plane: &Pose,
        half: [f32; 2],
        color: [f32; 3],
        strength: f32,
        offsets: [i32; 2],
        texture: Option<TexMap<'a>>,
    ) -> Ground<'a> {
        let r = cam_from_plane.rotation;
        let origin = cam_from_plane.translation_m.as_vec3();
        let normal = r.z_axis.as_vec3();
        Ground {
            origin,
            e1: r.x_axis.as_vec3(),
            e2: r.y_axis.as_vec3(),
            normal,
            num: normal.dot(origin),
            half_u: half[0],
            half_v: half[1],
            albedo_linear: color.map(srgb_to_linear_f32),
            strength: strength.clamp(0.0, 1.0),
            offsets,
            texture,
        }
    }

    /// Pixels of row `y` that can hold the plane, from the six linear constraints in x that
    /// make a hit (in front of the camera, beyond the near plane, inside the square), with a
    /// pixel of margin: the exact per-pixel test decides within it.
    pub fn row_span(&self, y: usize, proj: &Projection, width: usize) -> (usize, usize) {
        let (fx, fy) = (proj.fx as f64, proj.fy as f64);
        let (cx, cy) = (proj.cx as f64, proj.cy as f64);
        let num = self.num as f64;
        if num == 0.0 {
            return (0, 0); // the camera lies in the plane
        }
        let s = num.signum();
        let dy = (y as f64 - cy) / fy;
        // Ray of pixel x: d = (x / fx - cx / fx, dy, 1); n.d, e1.d, e2.d are affine in x.
        let aff = |v: Vec3| {
            let v = v.as_dvec3();
            (v.x / fx, -v.x * cx / fx + v.y * dy + v.z)
        };
        let (na, nb) = aff(self.normal);
        let (ua, ub) = aff(self.e1);
        let (va, vb) = aff(self.e2);
        let (uc, vc) = (
            self.e1.as_dvec3().dot(self.origin.as_dvec3()),
            self.e2.as_dvec3().dot(self.origin.as_dvec3()),
        );
        let (hu, hv) = (self.half_u as f64, self.half_v as f64);
        let near = proj.near_m as f64;
        // With D = n.d and s D > 0: t = num / D >= near  <=>  |num| - near s D >= 0;
        // u = num (e1.d) / D - uc in [-h, h)  <=>  s num (e1.d) - (uc -+ h) s D  >=< 0.
        let cons = [
            (s * na, s * nb),
            (-near * s * na, num.abs() - near * s * nb),
            (
                s * (num * ua - (uc - hu) * na),
                s * (num * ub - (uc - hu) * nb),
            ),
            (
                -s * (num * ua - (uc + hu) * na),
                -s * (num * ub - (uc + hu) * nb),
            ),
            (
                s * (num * va - (vc - hv) * na),
                s * (num * vb - (vc - hv) * nb),
            ),
            (
                -s * (num * va - (vc + hv) * na),
                -s * (num * vb - (vc + hv) * nb),
            ),
        ];
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for (a, b) in cons {
            // a x + b >= 0
            if a > 0.0 {
                lo = lo.max(-b / a);
            } else if a < 0.0 {
                hi = hi.min(-b / a);
            } else if b < 0.0 {
                return (0, 0);
            }
        }
        // Empty, or NaN from a degenerate pose.
        if lo.is_nan() || hi.is_nan() || lo > hi {
            return (0, 0);
        }
        let x0 = (lo.floor() - 1.0).clamp(0.0, width as f64) as usize;
        let x1 = (hi.ceil() + 2.0).clamp(0.0, width as f64) as usize;
        (x0, x1.max(x0))
    }

    /// The row's affine coefficients: pixel x of row `y` has the ray direction
    /// (x / fx - cx / fx, dy, 1), along which n.d, e1.d and e2.d are affine in x.
    #[inline(always)]
    fn row_coeffs(&self, y: usize, proj: &Projection) -> RowCoeffs {
        let (ifx, ify) = (1.0 / proj.fx, 1.0 / proj.fy);
        let (ox, dy) = (-proj.cx * ifx, (y as f32 - proj.cy) * ify);
        RowCoeffs {
            n_a: self.normal.x * ifx,
            n_b: self.normal.x * ox + self.normal.y * dy + self.normal.z,
            u_a: self.e1.x * ifx,
            u_b: self.e1.x * ox + self.e1.y * dy + self.e1.z,
            v_a: self.e2.x * ifx,
            v_b: self.e2.x * ox + self.e2.y * dy + self.e2.z,
            u_c: self.e1.dot(self.origin),
            v_c: self.e2.dot(self.origin),
        }
    }

    /// At the centre of pixel `xf` of the row: the plane depth where the ray hits the square
    /// beyond the near plane (else 0), and the plane coordinates (u, v) of the hit.
    /// Selects, not branches, so loops over it vectorize; NaN and inf fail the compares.
    #[inline(always)]
    fn eval(&self, c: &RowCoeffs, near: f32, xf: f32) -> (f32, f32, f32) {
        let tt = self.num / (c.n_a * xf + c.n_b);
        let u = tt * (c.u_a * xf + c.u_b) - c.u_c;
        let v = tt * (c.v_a * xf + c.v_b) - c.v_c;
        let (hu, hv) = (self.half_u, self.half_v);
        let hit = (tt >= near) & (u >= -hu) & (u < hu) & (v >= -hv) & (v < hv);
        (select(hit, tt, 0.0), u, v)
    }

    /// The plane's depth (z along the optical axis) at the centres of pixels `x0..` of row
    /// `y`: the ray-plane intersection where it lies beyond the near plane and inside the
    /// square, else 0.
    pub fn plane_depths(&self, y: usize, proj: &Projection, x0: usize, t: &mut [f32]) {
        let c = self.row_coeffs(y, proj);
        for (i, tv) in t.iter_mut().enumerate() {
            let xf = (x0 + i) as i32 as f32; // i32 converts in vector registers, usize does not
            *tv = self.eval(&c, proj.near_m, xf).0;
        }
    }

    /// Draws the plane into row `y`: per pixel centre the exact ray-plane depth (z along the
    /// optical axis) where the ray hits the square beyond the near plane, kept where nearer
    /// than (or as near as) the objects already in `depth` (instance 0); then its colour,
    /// ground colour x tile texture x (ambient + Lambert, no specular), written over the
    /// row's whole ground span. The caller draws objects and background over it.
    #[allow(clippy::too_many_arguments)]
    pub fn draw_row(
        &self,
        y: usize,
        proj: &Projection,
        params: &ShadeParams,
        lights: &[Light],
        tables: &TileTables,
        luts: &ColorLuts,
        depth: &mut [f32],
        instance: &mut [u16],
        rgb: &mut [u8],
        row: &mut GroundRow,
    ) {
        let (s0, s1) = self.row_span(y, proj, depth.len());
        if s0 >= s1 {
            return;
        }
        let GroundRow {
            t,
            tile,
            pattern,
            f,
            fc,
            samples,
        } = row;

        // One vectorized pass over the span: plane depth (kept in `t` for shading), depth
        // test against the objects, and the fine tile under the pixel centre.
        let sw = s1 - s0;
        t.resize(sw, 0.0);
        tile.resize(sw, 0);
        let c = self.row_coeffs(y, proj);
        let [otx, oty] = self.offsets;
        for (i, (((tv, k), d), id)) in t[..sw]
            .iter_mut()
            .zip(&mut tile[..sw])
            .zip(&mut depth[s0..s1])
            .zip(&mut instance[s0..s1])
            .enumerate()
        {
            let xf = (s0 + i) as i32 as f32;
            let (tt, u, v) = self.eval(&c, proj.near_m, xf);
            *tv = tt;
            let win = (tt > 0.0) & ((*d == 0.0) | (tt <= *d));
            *d = select(win, tt, *d);
            *id &= !0u16.wrapping_sub(win as u16);
            let fu = floor_low_bits(u * (1.0 / FINE_TILE_M)) + otx;
            let fv = floor_low_bits(v * (1.0 / FINE_TILE_M)) + oty;
            *k = ((fu & TILE_MASK) | ((fv & TILE_MASK) << TILES_LOG2)) as u32;
        }
        // The hits of a row lie on a line of the plane, whose intersection with the square is
        // one segment: shade from the first hit to the last.
        let Some(first) = t[..sw].iter().position(|&v| v > 0.0) else {
            return;
        };
        let last = t[..sw].iter().rposition(|&v| v > 0.0).map_or(first, |l| l) + 1;
        let (x0, x1) = (s0 + first, s0 + last);
        let w = x1 - x0;
        let t = &t[first..last];

        // Texture factor per pixel and channel, padded with 1 to whole chunks of LIGHT_STEP
        // pixels. Procedural tiles: mean 1, contrast `strength`, the same for the three
        // channels (the table lookups alone in a scalar pass, the arithmetic in a vectorized
        // one). An image: its linear texel at the mip level of the pixel's footprint.
        let wp = w.div_ceil(LIGHT_STEP) * LIGHT_STEP;
        let factors: [&[f32]; 3] = if let Some(tm) = &self.texture {
            let c = self.row_coeffs(y, proj);
            for fc in fc.iter_mut() {
                fc.resize(wp, 1.0);
                fc[w..wp].fill(1.0);
            }
            let [fr, fg, fb] = fc;
            for (i, ((r, g), b)) in fr[..w]
                .iter_mut()
                .zip(&mut fg[..w])
                .zip(&mut fb[..w])
                .enumerate()
            {
                let xf = (x0 + i) as i32 as f32;
                let (_, u, v) = self.eval(&c, proj.near_m, xf);
                // A pixel spans depth / (fx |n.d|) metres of the plane along its steepest
                // direction (d the pixel's ray with d.z = 1, depth = num / n.d).
                let nd = c.n_a * xf + c.n_b;
                let foot = (self.num / (proj.fx * nd * nd)).abs();
                [*r, *g, *b] = tm.fetch(u, v, foot);
            }
            [&fr[..], &fg[..], &fb[..]]
        } else {
            pattern.resize(w, 0);
            for (p, &k) in pattern[..w].iter_mut().zip(&tile[first..last]) {
                *p = tables.pattern[k as usize & (TILES * TILES - 1)];
            }
            f.resize(wp, 0.0);
            let s2 = self.strength * 2.0;
            for (fx, &p) in f[..w].iter_mut().zip(&pattern[..w]) {
                *fx = 1.0 + s2 * (p as f32 / 255.0 - 0.5);
            }
            f[w..wp].fill(1.0);
            [&f[..], &f[..], &f[..]]
        };

        // Irradiance x albedo, pre-scaled to the sRGB table's range: exact every LIGHT_STEP
        // pixels and linear in between (it varies slowly over the plane). On the plane
        // n.(L - p) is the light's height above it, the same for every pixel, so Lambert
        // reduces to height / distance. Pixel x0 + i has the ray direction (ox + i / fx, dy, 1).
        let (ifx, ify) = (1.0 / proj.fx, 1.0 / proj.fy);
        let dy = (y as f32 - proj.cy) * ify;
        let ox = (x0 as f32 - proj.cx) * ifx;
        let scale = self.albedo_linear.map(|a| a * TO_SRGB_MAX as f32);
        let side = if self.num > 0.0 { -1.0 } else { 1.0 };
        // The plane's face towards the camera takes the environment's light from its side.
        let ambient =
            params.ambient_towards(self.normal * side, params.env.map_or(Vec3::Z, |e| e.up_cam));
        let ns = (w - 1) / LIGHT_STEP + 2;
        samples.clear();
        for s in 0..ns {
            let i = (s * LIGHT_STEP).min(w - 1);
            let ti = t[i];
            let p = Vec3::new((ox + i as f32 * ifx) * ti, dy * ti, ti);
            let mut es = ambient;
            for l in lights {
                let height = side * (self.normal.dot(l.position) - self.num);
                if height > 0.0 {
                    let k = height / (l.position - p).length();
                    for (ec, lc) in es.iter_mut().zip(l.color) {
                        *ec += lc * k;
                    }
                }
            }
            samples.push(std::array::from_fn(|c| es[c] * scale[c]));
        }

        // Per chunk of LIGHT_STEP pixels: irradiance linear between its samples x texture ->
        // sRGB table indices (vectorized, in registers), then the table lookups packed four
        // pixels to three 32-bit stores.
        let samples = &samples[..];
        let mut ix = [[0u32; LIGHT_STEP]; 3];
        let out = &mut rgb[x0 * 3..x1 * 3];
        let mut px_chunks = out.chunks_exact_mut(3 * LIGHT_STEP);
        let chunk = |c: usize, start: usize| {
            <&[f32; LIGHT_STEP]>::try_from(&factors[c][start..start + LIGHT_STEP])
        };
        for (s, px) in px_chunks.by_ref().enumerate() {
            // Fixed-size arrays, so the inner loops unroll (the conversions cannot fail).
            let o = s * LIGHT_STEP;
            if let (Ok(px), Ok(f0), Ok(f1), Ok(f2)) = (
                <&mut [u8; 3 * LIGHT_STEP]>::try_from(px),
                chunk(0, o),
                chunk(1, o),
                chunk(2, o),
            ) {
                chunk_indices(&samples[s..s + 2], [f0, f1, f2], LIGHT_STEP as f32, &mut ix);
                pack_chunk(&ix, px, luts);
            }
        }
        let rest = px_chunks.into_remainder();
        if !rest.is_empty() {
            // The last, partial chunk ends at the row's last hit, where its sample is taken.
            let s = w / LIGHT_STEP;
            let done = s * LIGHT_STEP;
            let den = ((w - done).max(2) - 1) as f32;
            if let (Ok(f0), Ok(f1), Ok(f2)) = (chunk(0, done), chunk(1, done), chunk(2, done)) {
                chunk_indices(&samples[s..s + 2], [f0, f1, f2], den, &mut ix);
            }
            for (i, px) in rest.chunks_exact_mut(3).enumerate() {
                px[0] = luts.srgb_at(ix[0][i] as u16);
                px[1] = luts.srgb_at(ix[1][i] as u16);
                px[2] = luts.srgb_at(ix[2][i] as u16);
            }
        }
    }

    /// Draws a wall into row `y` where it is nearer than what `depth` holds (or ties; it
    /// has instance 0): depth, and colour = colour x texture x (ambient + Lambert), every
    /// pixel exact. Unlike `draw_row` it writes colour only where it wins, so walls and the
    /// ground may be drawn in any order.
    #[allow(clippy::too_many_arguments)]
    pub fn draw_row_masked(
        &self,
        y: usize,
        proj: &Projection,
        params: &ShadeParams,
        lights: &[Light],
        luts: &ColorLuts,
        depth: &mut [f32],
        instance: &mut [u16],
        rgb: &mut [u8],
    ) {
        let (s0, s1) = self.row_span(y, proj, depth.len());
        if s0 >= s1 {
            return;
        }
        let c = self.row_coeffs(y, proj);
        let (ifx, ify) = (1.0 / proj.fx, 1.0 / proj.fy);
        let dy = (y as f32 - proj.cy) * ify;
        let scale = self.albedo_linear.map(|a| a * TO_SRGB_MAX as f32);
        let side = if self.num > 0.0 { -1.0 } else { 1.0 };
        // The plane's face towards the camera takes the environment's light from its side.
        let ambient =
            params.ambient_towards(self.normal * side, params.env.map_or(Vec3::Z, |e| e.up_cam));
        for x in s0..s1 {
            let xf = x as i32 as f32;
            let (tt, u, v) = self.eval(&c, proj.near_m, xf);
            let d = depth[x];
            if !(tt > 0.0 && (d == 0.0 || tt <= d)) {
                continue;
            }
            depth[x] = tt;
            instance[x] = 0;
            let p = Vec3::new((xf - proj.cx) * ifx * tt, dy * tt, tt);
            let mut e = ambient;
            for l in lights {
                // The light's height above the plane, on the camera's side.
                let h = side * (self.normal.dot(l.position) - self.num);
                if h > 0.0 {
                    let k = h / (l.position - p).length();
                    for (ec, lc) in e.iter_mut().zip(l.color) {
                        *ec += lc * k;
                    }
                }
            }
            let tex = match &self.texture {
                Some(tm) => {
                    let nd = c.n_a * xf + c.n_b;
                    tm.fetch(u, v, (self.num / (proj.fx * nd * nd)).abs())
                }
                None => [1.0; 3],
            };
            for ch in 0..3 {
                rgb[x * 3 + ch] = luts.srgb_at(srgb_index32(e[ch] * scale[ch] * tex[ch]) as u16);
            }
        }
    }
}

/// Per-row coefficients of `Ground::eval`.
struct RowCoeffs {
    n_a: f32,
    n_b: f32,
    u_a: f32,
    u_b: f32,
    v_a: f32,
    v_b: f32,
    u_c: f32,
    v_c: f32,
}

/// Pixels between exact irradiance samples along a ground row.
const LIGHT_STEP: usize = 16;

/// 0, 1, .., LIGHT_STEP - 1 as floats.
const RAMP: [f32; LIGHT_STEP] = {
    let mut r = [0.0; LIGHT_STEP];
    let mut i = 0;
    while i < LIGHT_STEP {
        r[i] = i as f32;
        i += 1;
    }
    r
};

/// sRGB table indices per channel for a chunk of pixels: irradiance linear from
/// `samples[0]` in steps of (`samples[1]` - `samples[0]`) / `den`, times the channel's
/// texture factor.
#[inline(always)]
fn chunk_indices(
    samples: &[[f32; 3]],
    fs: [&[f32; LIGHT_STEP]; 3],
    den: f32,
    ix: &mut [[u32; LIGHT_STEP]; 3],
) {
    let (s0, s1) = (samples[0], samples[1]);
    for (c, (ixc, fs)) in ix.iter_mut().zip(fs).enumerate() {
        let a = s0[c];
        let step = (s1[c] - a) / den;
        for ((o, &fx), r) in ixc.iter_mut().zip(fs).zip(RAMP) {
            *o = srgb_index32((a + step * r) * fx);
        }
    }
}

/// The sRGB bytes of a chunk of pixels from their table indices per channel, written four
/// pixels (12 bytes) at a time as three 32-bit words instead of twelve byte stores.
#[inline(always)]
fn pack_chunk(ix: &[[u32; LIGHT_STEP]; 3], px: &mut [u8; 3 * LIGHT_STEP], luts: &ColorLuts) {
    for (q, out) in px.chunks_exact_mut(12).enumerate() {
        let i = 4 * q;
        let b = |c: usize, j: usize| luts.srgb_at(ix[c][(i + j) % LIGHT_STEP] as u16) as u32;
        let w0 = b(0, 0) | b(1, 0) << 8 | b(2, 0) << 16 | b(0, 1) << 24;
        let w1 = b(1, 1) | b(2, 1) << 8 | b(0, 2) << 16 | b(1, 2) << 24;
        let w2 = b(2, 2) | b(0, 3) << 8 | b(1, 3) << 16 | b(2, 3) << 24;
        out[0..4].copy_from_slice(&w0.to_le_bytes());
        out[4..8].copy_from_slice(&w1.to_le_bytes());
        out[8..12].copy_from_slice(&w2.to_le_bytes());
    }
}

/// Row buffers for `Ground::draw_row`, reused across rows and frames.
#[derive(Debug, Default)]
pub(crate) struct GroundRow {
    /// Plane depth per pixel.
    t: Vec<f32>,
    /// Tile table index per pixel.
    tile: Vec<u32>,
    /// Tile pattern byte per pixel.
    pattern: Vec<u8>,
    /// Texture factor per pixel.
    f: Vec<f32>,
    /// Image texture factor per channel and pixel.
    fc: [Vec<f32>; 3],
    /// Exact irradiance samples along the row.
    samples: Vec<[f32; 3]>,
}

/// A fast 32-bit integer hash (lowbias32).
#[inline(always)]
pub(crate) fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use synthgen_core::glam::{DMat3, DVec3};

    fn ground(rot: DMat3, t: DVec3, size_m: f64) -> Ground<'static> {
        Ground::new(
            &GroundInstance {
                cam_from_plane: Pose::new(rot, t),
                size_m,
                color: [0.5; 3],
                texture_strength: 0.3,
                texture_seed: 1,
                texture: None,
            },
            None,
        )
    }

    /// The analytic span of each row holds every pixel the exact per-pixel test hits.
    #[test]
    fn row_span_contains_every_hit() {
        let proj = Projection {
            fx: 572.4,
            fy: 573.6,
            cx: 325.3,
            cy: 242.0,
            near_m: 0.01,
        };
        let (w, h) = (640usize, 480usize);
        let mut t = vec![0.0f32; w];
        let mut hits = 0usize;
        let mut state = 7u64;
        let mut rnd = || {
            state = synthgen_core::rng::splitmix64(state);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..60 {
            let axis = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let rot = DMat3::from_axis_angle(axis, rnd() * 6.3);
            let pos = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() * 2.0 - 0.3);
            let size = if case % 3 == 0 { 0.3 } else { 3.0 };
            let g = ground(rot, pos, size);
            for y in 0..h {
                g.plane_depths(y, &proj, 0, &mut t);
                let (s0, s1) = g.row_span(y, &proj, w);
                for (x, &tv) in t.iter().enumerate() {
                    if tv > 0.0 {
                        hits += 1;
                        assert!(
                            x >= s0 && x < s1,
                            "case {case} row {y}: hit at {x} outside {s0}..{s1}"
                        );
                    }
                }
            }
        }
        assert!(
            hits > 100_000,
            "the cases should see the plane: {hits} hits"
        );
    }
}
