//! Deferred shading of object pixels: from the nearest triangle's id, recompute exact
//! perspective-correct barycentrics by intersecting the pixel-centre ray with the triangle
//! (in the object frame), then Lambert + Blinn-Phong in linear light, or (`[materials]
//! shading = "ggx"`) Lambert + a GGX microfacet lobe (Smith shadowing, Schlick's Fresnel)
//! with metalness.

use synthgen_core::glam::{Mat3, Vec3};
use synthgen_core::sample::PointLight;
use synthgen_core::{ObjectInstance, Texture};

use crate::color::{srgb_index, ColorLuts, TO_SRGB_MAX};
use crate::prepare::{PreparedModel, PreparedPrimitive, ShadeVert};
use crate::raster::Projection;

/// A point light in some frame, colour premultiplied by intensity (linear).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Light {
    pub position: Vec3,
    pub color: [f32; 3],
}

impl Light {
    pub fn from_point_light(l: &PointLight) -> Light {
        Light {
            position: l.position_cam_m.as_vec3(),
            color: l.color.map(|c| c.max(0.0) * l.intensity.max(0.0)),
        }
    }
}

/// Per-frame shading constants.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ShadeParams {
    pub ambient: f32,
    pub ggx: bool,
    /// The environment light: sky and ground colours and the world's up in the camera frame.
    pub env: Option<Environment>,
}

/// A two-colour hemisphere light probe (`[lights] sky_color`, `ground_color`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Environment {
    pub sky: [f32; 3],
    pub ground: [f32; 3],
    /// World +z in the camera frame.
    pub up_cam: Vec3,
}

impl ShadeParams {
    /// The ambient light (per channel) on a surface of unit normal `n` in the frame where
    /// the world's up is `up`: uniform without an environment, else the sky and ground
    /// colours mixed by (1 + n·up) / 2.
    #[inline]
    pub fn ambient_towards(&self, n: Vec3, up: Vec3) -> [f32; 3] {
        match &self.env {
            None => [self.ambient; 3],
            Some(e) => {
                let t = (0.5 + 0.5 * n.dot(up)).clamp(0.0, 1.0);
                std::array::from_fn(|c| self.ambient * (e.ground[c] + (e.sky[c] - e.ground[c]) * t))
            }
        }
    }
}

/// Per-object shading buffers (structure of arrays over the object's visible pixels),
/// reused across objects and frames.
#[derive(Debug, Default)]
pub(crate) struct ShadeBatch {
    /// Output pixel index, triangle id and pixel coordinates of each visible pixel.
    pub pixel: Vec<u32>,
    pub tri: Vec<u32>,
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    v0: [Vec<f32>; 3],
    e1: [Vec<f32>; 3],
    e2: [Vec<f32>; 3],
    /// Surface point (object frame) and unnormalized normal.
    p: [Vec<f32>; 3],
    n: [Vec<f32>; 3],
    /// Barycentric weights of vertices 1 and 2.
    b: [Vec<f32>; 2],
    albedo: [Vec<f32>; 3],
    diffuse: [Vec<f32>; 3],
    spec: [Vec<f32>; 3],
    idx: Vec<[u16; 3]>,
}

impl ShadeBatch {
    pub fn clear(&mut self) {
        self.pixel.clear();
        self.tri.clear();
        self.x.clear();
        self.y.clear();
    }

    pub fn push(&mut self, pixel: u32, tri: u32, x: i32, y: i32) {
        self.pixel.push(pixel);
        self.tri.push(tri);
        self.x.push(x as f32);
        self.y.push(y as f32);
    }
}

fn sized<const N: usize>(v: &mut [Vec<f32>; N], n: usize) -> [&mut [f32]; N] {
    for a in v.iter_mut() {
        a.resize(n, 0.0);
    }
    v.each_mut().map(|a| &mut a[..n])
}

/// Shades the pixels gathered in `batch` (one object), writing sRGB into `rgb` at each
/// pixel's index. Split into passes so that the arithmetic runs as vectorizable loops over
/// arrays, with only the vertex gathers and table lookups left scalar.
#[allow(clippy::too_many_arguments)]
pub(crate) fn shade_pixels(
    model: &PreparedModel,
    inst: &ObjectInstance,
    proj: &Projection,
    params: &ShadeParams,
    cam_lights: &[Light],
    luts: &ColorLuts,
    batch: &mut ShadeBatch,
    rgb: &mut [u8],
) {
    let n = batch.pixel.len();
    if n == 0 {
        return;
    }
    let rot: Mat3 = inst.cam_from_obj.rotation.as_mat3();
    let t = inst.cam_from_obj.translation_m.as_vec3();
    let obj_from_cam = rot.transpose();
    let eye = obj_from_cam * -t;
    // Ray of pixel (x, y): d_cam = ((x - cx) / fx, (y - cy) / fy, 1), in the object frame.
    let (r0, r1, r2) = (
        obj_from_cam.x_axis,
        obj_from_cam.y_axis,
        obj_from_cam.z_axis,
    );
    let dir_x = r0 / proj.fx;
    let dir_y = r1 / proj.fy;
    let dir_0 = r2 - r0 * (proj.cx / proj.fx) - r1 * (proj.cy / proj.fy);
    let brightness = inst.brightness.max(0.0);
    // Base colour transform: brightness x tint x hue rotation (linear light).
    let tint = inst.tint.map(|t| t.max(0.0) * brightness);
    let hue =
        (inst.hue_deg != 0.0).then(|| synthgen_core::color::hue_rotation(f64::from(inst.hue_deg)));
    let specular = inst.specular.max(0.0);
    let shininess = inst.shininess.max(0.0);

    let ShadeBatch {
        tri,
        x: xs,
        y: ys,
        v0,
        e1,
        e2,
        p,
        n: nrm,
        b,
        albedo,
        diffuse,
        spec,
        idx,
        pixel,
    } = batch;
    let (tri, xs, ys) = (&tri[..n], &xs[..n], &ys[..n]);
    let [v0x, v0y, v0z] = sized(v0, n);
    let [e1x, e1y, e1z] = sized(e1, n);
    let [e2x, e2y, e2z] = sized(e2, n);

    // A: gather the triangles (scalar).
    for k in 0..n {
        let [i0, i1, i2] = model.tris[tri[k] as usize];
        let (a, bb, c) = (
            model.verts[i0 as usize].p,
            model.verts[i1 as usize].p,
            model.verts[i2 as usize].p,
        );
        v0x[k] = a.x;
        v0y[k] = a.y;
        v0z[k] = a.z;
        e1x[k] = bb.x - a.x;
        e1y[k] = bb.y - a.y;
        e1z[k] = bb.z - a.z;
        e2x[k] = c.x - a.x;
        e2y[k] = c.y - a.y;
        e2z[k] = c.z - a.z;
    }

    // B: exact barycentrics of the pixel-centre ray (Moller-Trumbore), clamped because the
    // centre can sit a hair outside the exact triangle (vertices were snapped to 1/256 px
    // for coverage); then the surface point.
    let [b1s, b2s] = sized(b, n);
    let [px, py, pz] = sized(p, n);
    for k in 0..n {
        let d = dir_x * xs[k] + dir_y * ys[k] + dir_0;
        let e1 = Vec3::new(e1x[k], e1y[k], e1z[k]);
        let e2 = Vec3::new(e2x[k], e2y[k], e2z[k]);
        let v0 = Vec3::new(v0x[k], v0y[k], v0z[k]);
        let pvec = d.cross(e2);
        let det = e1.dot(pvec);
        let inv = 1.0 / det;
        let tvec = eye - v0;
        let qvec = tvec.cross(e1);
        let ok = det.abs() > 1e-20;
        let b1 = if ok { tvec.dot(pvec) * inv } else { 1.0 / 3.0 };
        let b2 = if ok { d.dot(qvec) * inv } else { 1.0 / 3.0 };
        let (b1, b2) = (b1.clamp(0.0, 1.0), b2.clamp(0.0, 1.0));
        let s = 1.0 / (b1 + b2).max(1.0);
        let (b1, b2) = (b1 * s, b2 * s);
        b1s[k] = b1;
        b2s[k] = b2;
        let q = v0 + e1 * b1 + e2 * b2;
        px[k] = q.x;
        py[k] = q.y;
        pz[k] = q.z;
    }

    // C: normal and albedo from the vertices (scalar: gathers, textures, primitive flags).
    let [nx, ny, nz] = sized(nrm, n);
    let [ar, ag, ab] = sized(albedo, n);
    let mut hint = 0;
    for k in 0..n {
        let id = tri[k];
        hint = model.prim_of(id, hint);
        let prim = &model.prims[hint];
        let vi = model.tris[id as usize];
        let sv = vi.map(|i| &model.verts[i as usize]);
        let (b1, b2) = (b1s[k], b2s[k]);
        let w = [1.0 - b1 - b2, b1, b2];
        let face = Vec3::new(e1x[k], e1y[k], e1z[k]).cross(Vec3::new(e2x[k], e2y[k], e2z[k]));
        let mut nv = if prim.has_normals {
            sv[0].n * w[0] + sv[1].n * w[1] + sv[2].n * w[2]
        } else {
            face
        };
        if prim.double_sided && face.dot(eye - Vec3::new(px[k], py[k], pz[k])) < 0.0 {
            nv = -nv;
        }
        nx[k] = nv.x;
        ny[k] = nv.y;
        nz[k] = nv.z;
        let a = albedo_at(prim, vi, sv, w, luts);
        let a = match &hue {
            None => a,
            Some(m) => {
                std::array::from_fn(|i| (m[i][0] * a[0] + m[i][1] * a[1] + m[i][2] * a[2]).max(0.0))
            }
        };
        ar[k] = a[0] * tint[0];
        ag[k] = a[1] * tint[1];
        ab[k] = a[2] * tint[2];
    }

    // D: lighting, one vectorizable pass per light, after normalizing the normals.
    // (Keeping the view vector in arrays for all lights measured slower than recomputing it.)
    let [dr, dg, db] = sized(diffuse, n);
    let [sr, sg, sb] = sized(spec, n);
    dr.fill(params.ambient);
    dg.fill(params.ambient);
    db.fill(params.ambient);
    sr.fill(0.0);
    sg.fill(0.0);
    sb.fill(0.0);
    for k in 0..n {
        let nv = normalize(Vec3::new(nx[k], ny[k], nz[k]));
        nx[k] = nv.x;
        ny[k] = nv.y;
        nz[k] = nv.z;
    }
    if let Some(e) = &params.env {
        let up = obj_from_cam * e.up_cam;
        for k in 0..n {
            let a = params.ambient_towards(Vec3::new(nx[k], ny[k], nz[k]), up);
            dr[k] = a[0];
            dg[k] = a[1];
            db[k] = a[2];
        }
    }
    if params.ggx {
        // Metals: no diffuse part, a specular colour of the base colour.
        let metallic = inst.metallic.clamp(0.0, 1.0);
        let f0_dielectric = 0.08 * specular.min(1.0);
        let alpha = ggx_alpha(shininess);
        for l in cam_lights {
            let lp = obj_from_cam * (l.position - t);
            let col = l.color;
            for k in 0..n {
                let q = Vec3::new(px[k], py[k], pz[k]);
                let nv = Vec3::new(nx[k], ny[k], nz[k]);
                let ld = normalize(lp - q);
                let v = normalize(eye - q);
                let ndl = nv.dot(ld);
                let lam = ndl.max(0.0) * (1.0 - metallic);
                let (lobe, fresnel) = ggx_lobe(nv, ld, v, alpha);
                let albedo = [ar[k], ag[k], ab[k]];
                let f = albedo.map(|a| {
                    let f0 = f0_dielectric + (a.min(1.0) - f0_dielectric) * metallic;
                    f0 + (1.0 - f0) * fresnel
                });
                dr[k] += col[0] * lam;
                dg[k] += col[1] * lam;
                db[k] += col[2] * lam;
                sr[k] += col[0] * lobe * f[0];
                sg[k] += col[1] * lobe * f[1];
                sb[k] += col[2] * lobe * f[2];
            }
        }
        // (The ambient term stays albedo × ambient: a metal's specular colour is its base
        // colour, so an ambient light reaching it through either part looks the same.)
    }
    for l in cam_lights.iter().filter(|_| !params.ggx) {
        let lp = obj_from_cam * (l.position - t);
        let col = l.color;
        for k in 0..n {
            let q = Vec3::new(px[k], py[k], pz[k]);
            let nv = Vec3::new(nx[k], ny[k], nz[k]);
            let ld = normalize(lp - q);
            let v = normalize(eye - q);
            let ndl = nv.dot(ld);
            let lam = ndl.max(0.0);
            let h = normalize(ld + v);
            let ndh = nv.dot(h).max(0.0);
            let sp = if ndl > 0.0 {
                specular * fast_pow(ndh, shininess)
            } else {
                0.0
            };
            dr[k] += col[0] * lam;
            dg[k] += col[1] * lam;
            db[k] += col[2] * lam;
            sr[k] += col[0] * sp;
            sg[k] += col[1] * sp;
            sb[k] += col[2] * sp;
        }
    }

    // E: final colour to sRGB table indices, then F: the table lookups.
    idx.resize(n, [0; 3]);
    let idx = &mut idx[..n];
    for k in 0..n {
        idx[k] = [
            srgb_index((ar[k] * dr[k] + sr[k]) * TO_SRGB_MAX as f32),
            srgb_index((ag[k] * dg[k] + sg[k]) * TO_SRGB_MAX as f32),
            srgb_index((ab[k] * db[k] + sb[k]) * TO_SRGB_MAX as f32),
        ];
    }
    for (&o, ix) in pixel[..n].iter().zip(idx.iter()) {
        let o = o as usize * 3;
        if let Some(px) = rgb.get_mut(o..o + 3) {
            px[0] = luts.srgb_at(ix[0]);
            px[1] = luts.srgb_at(ix[1]);
            px[2] = luts.srgb_at(ix[2]);
        }
    }
}

/// GGX α from the instance's Blinn-Phong exponent n: roughness r = (2 / (n + 2))^¼ (the
/// inverse of `[materials] roughness`'s n = 2 / r⁴ − 2), α = r², kept ≥ 0.02 (a mirror's
/// highlight would be a single pixel).
#[inline]
pub(crate) fn ggx_alpha(shininess: f32) -> f32 {
    let r = (2.0 / (shininess.max(0.0) + 2.0)).sqrt().sqrt();
    (r * r).max(0.02)
}

/// The GGX specular lobe for unit normal `n`, light `l` and view `v`, scaled as the diffuse
/// term is (radiance × π, so that a white Lambert surface under light I facing it gives I):
/// π D G / (4 n·v) · (the n·l of the rendering equation cancels one of the BRDF's), and
/// Schlick's Fresnel weight (1 − v·h)⁵ (the caller mixes F0 with it). Zero when the light or
/// the eye is below the surface.
#[inline(always)]
pub(crate) fn ggx_lobe(n: Vec3, l: Vec3, v: Vec3, alpha: f32) -> (f32, f32) {
    let ndl = n.dot(l);
    let ndv = n.dot(v);
    if ndl <= 0.0 || ndv <= 0.0 {
        return (0.0, 0.0);
    }
    let h = normalize(l + v);
    let ndh = n.dot(h).max(0.0);
    let a2 = alpha * alpha;
    let d_den = ndh * ndh * (a2 - 1.0) + 1.0;
    let d = a2 / (std::f32::consts::PI * d_den * d_den);
    // Smith-Schlick with k = α / 2 (Karis' fit to Smith GGX).
    let kk = alpha * 0.5;
    let g1 = |x: f32| x / (x * (1.0 - kk) + kk);
    let g = g1(ndl) * g1(ndv);
    let lobe = std::f32::consts::PI * d * g / (4.0 * ndv);
    let vdh = v.dot(h).clamp(0.0, 1.0);
    let m = 1.0 - vdh;
    let m2 = m * m;
    (lobe, m2 * m2 * m)
}

/// `v / |v|`, zero for a zero vector; branch-free.
#[inline(always)]
fn normalize(v: Vec3) -> Vec3 {
    let l2 = v.dot(v);
    let inv = if l2 > 0.0 { 1.0 / l2.sqrt() } else { 0.0 };
    v * inv
}

/// Base colour (linear) at barycentric weights `w` of a triangle with global vertex indices
/// `vi` and vertices `sv`.
#[inline]
fn albedo_at(
    prim: &PreparedPrimitive,
    vi: [u32; 3],
    sv: [&ShadeVert; 3],
    w: [f32; 3],
    luts: &ColorLuts,
) -> [f32; 3] {
    let base = prim.base_linear;
    if let Some((tex, uvs)) = &prim.texture {
        let local = vi.map(|i| (i - prim.vert_base) as usize);
        let uv = uvs[local[0]] * w[0] + uvs[local[1]] * w[1] + uvs[local[2]] * w[2];
        let t = sample_bilinear(tex, uv.x, uv.y, luts);
        return std::array::from_fn(|c| base[c] * t[c]);
    }
    if prim.has_colors {
        let lin = |v: &ShadeVert, c: usize| luts.to_linear[v.rgb[c] as usize];
        return std::array::from_fn(|c| {
            base[c] * (lin(sv[0], c) * w[0] + lin(sv[1], c) * w[1] + lin(sv[2], c) * w[2])
        });
    }
    base
}

/// Bilinear texture lookup with wrapping, in linear light. `v = 0` is the first row.
fn sample_bilinear(t: &Texture, u: f32, v: f32, luts: &ColorLuts) -> [f32; 3] {
    let (w, h) = (t.width as i64, t.height as i64);
    let fx = u * w as f32 - 0.5;
    let fy = v * h as f32 - 0.5;
    if !(fx.is_finite() && fy.is_finite()) {
        return [0.0; 3];
    }
    let (x0f, y0f) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - x0f, fy - y0f);
    let (x0, y0) = ((x0f as i64).rem_euclid(w), (y0f as i64).rem_euclid(h));
    let (x1, y1) = ((x0 + 1) % w, (y0 + 1) % h);
    let texel = |x: i64, y: i64| {
        let i = ((y * w + x) * 3) as usize;
        [
            luts.to_linear[t.rgb[i] as usize],
            luts.to_linear[t.rgb[i + 1] as usize],
            luts.to_linear[t.rgb[i + 2] as usize],
        ]
    };
    let (a, b, c, d) = (texel(x0, y0), texel(x1, y0), texel(x0, y1), texel(x1, y1));
    std::array::from_fn(|i| {
        let top = a[i] + (b[i] - a[i]) * ax;
        let bot = c[i] + (d[i] - c[i]) * ax;
        top + (bot - top) * ay
    })
}

/// x^y for x in 0..1, y >= 0, to about 1e-5 relative (plenty for a highlight):
/// exp2(y * log2(x)) with bit-trick log2/exp2 refined by short series. Branch-free so it
/// vectorizes.
#[inline(always)]
pub(crate) fn fast_pow(x: f32, y: f32) -> f32 {
    let xs = x.max(1e-30);
    let l = (y * fast_log2(xs)).max(-126.0);
    let r = fast_exp2(l);
    if x > 0.0 && l > -126.0 {
        r
    } else {
        0.0
    }
}

#[inline(always)]
fn fast_log2(x: f32) -> f32 {
    let bits = x.to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000); // 1..2
    let big = m > std::f32::consts::SQRT_2;
    let m = if big { m * 0.5 } else { m };
    let e = e + big as i32;
    // log2(m) = 2/ln2 * atanh(s), s = (m - 1) / (m + 1), |s| < 0.172.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let at = s * (1.0 + s2 * (1.0 / 3.0 + s2 * (1.0 / 5.0 + s2 * (1.0 / 7.0))));
    e as f32 + at * (2.0 * std::f32::consts::LOG2_E)
}

#[inline(always)]
fn fast_exp2(x: f32) -> f32 {
    // x in [-126, 0]: adding 1.5 * 2^23 rounds to an integer kept in the low mantissa bits
    // (no libm floor).
    const MAGIC: f32 = 12_582_912.0;
    let r = x + MAGIC;
    let xi = r - MAGIC;
    let f = (x - xi) * std::f32::consts::LN_2; // |f| <= ln2 / 2
    let p = 1.0 + f * (1.0 + f * (0.5 + f * (1.0 / 6.0 + f * (1.0 / 24.0 + f * (1.0 / 120.0)))));
    let i = (r.to_bits() & 0x7f_ffff) as i32 - 0x40_0000;
    let e = (i + 127).clamp(1, 254) as u32;
    f32::from_bits(e << 23) * p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lobe against the closed forms: at normal incidence (n = l = v) D = 1 / (π α²),
    /// G = 1, so π D G / 4 = 1 / (4 α²); Fresnel's weight is 0 there and grows to 1 at
    /// grazing; the lobe integrates (with the cosine) to the directional albedo that an
    /// independent numerical integral gives, never above 1.
    #[test]
    fn ggx_lobe_matches_closed_forms_and_conserves_energy() {
        let n = Vec3::Z;
        for alpha in [0.1f32, 0.3, 0.6, 1.0] {
            let (lobe, f) = ggx_lobe(n, n, n, alpha);
            let want = 1.0 / (4.0 * alpha * alpha);
            assert!(
                (lobe - want).abs() < 1e-4 * want,
                "α {alpha}: {lobe} vs {want}"
            );
            assert_eq!(f, 0.0);
            // ∫ lobe / π · cos θ_l dω_l for a view at 30°: the directional albedo (F = 1).
            let v = Vec3::new(0.5, 0.0, 0.866_025_4);
            let (mut sum, steps) = (0.0f64, 400);
            for i in 0..steps {
                let th = (i as f32 + 0.5) / steps as f32 * std::f32::consts::FRAC_PI_2;
                for j in 0..steps {
                    let ph = (j as f32 + 0.5) / steps as f32 * 2.0 * std::f32::consts::PI;
                    let l = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                    let (lb, _) = ggx_lobe(n, l, v, alpha);
                    let dw = th.sin()
                        * (std::f32::consts::FRAC_PI_2 / steps as f32)
                        * (2.0 * std::f32::consts::PI / steps as f32);
                    sum += f64::from(lb / std::f32::consts::PI * dw);
                }
            }
            // Single-scattering GGX loses energy as it roughens; numpy's integral of the same
            // formulas: 0.968, 0.819, 0.563, 0.329 (exact Smith G: 0.986, 0.864, 0.594, 0.329).
            let want = match alpha {
                a if a < 0.2 => 0.968,
                a if a < 0.5 => 0.819,
                a if a < 0.9 => 0.563,
                _ => 0.329,
            };
            assert!(
                sum <= 1.0 && (sum - want).abs() < 0.005,
                "α {alpha}: directional albedo {sum}, want {want}"
            );
        }
        let grazing = Vec3::new(0.999, 0.0, 0.0447).normalize();
        let (_, f) = ggx_lobe(n, grazing, Vec3::new(-0.999, 0.0, 0.0447).normalize(), 0.3);
        assert!(f > 0.75, "Schlick's weight at grazing: {f}");
        // roughness ↔ shininess round trip: n = 2 / r⁴ − 2.
        for r in [0.2f32, 0.5, 0.9] {
            let n = 2.0 / r.powi(4) - 2.0;
            assert!((ggx_alpha(n) - r * r).abs() < 1e-5);
        }
    }

    /// The hemisphere probe: facing up gives sky × ambient, down ground × ambient, sideways
    /// their mean; without it, the ambient from everywhere.
    #[test]
    fn environment_light_mixes_sky_and_ground_by_the_normal() {
        let mut p = ShadeParams {
            ambient: 0.5,
            ggx: false,
            env: None,
        };
        assert_eq!(p.ambient_towards(Vec3::X, Vec3::Z), [0.5; 3]);
        p.env = Some(Environment {
            sky: [1.2, 1.2, 1.4],
            ground: [0.4, 0.3, 0.2],
            up_cam: Vec3::Z,
        });
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(close(p.ambient_towards(Vec3::Z, Vec3::Z), [0.6, 0.6, 0.7]));
        assert!(close(
            p.ambient_towards(-Vec3::Z, Vec3::Z),
            [0.2, 0.15, 0.1]
        ));
        assert!(close(
            p.ambient_towards(Vec3::Y, Vec3::Z),
            [0.4, 0.375, 0.4]
        ));
    }

    #[test]
    fn fast_pow_is_close() {
        for &y in &[1.0f32, 8.0, 32.0, 64.0, 200.0] {
            for i in 1..=100 {
                let x = i as f32 / 100.0;
                let (a, b) = (fast_pow(x, y), x.powf(y));
                assert!((a - b).abs() <= 1e-4 * b + 1e-7, "{x}^{y}: {a} vs {b}");
            }
        }
        assert_eq!(fast_pow(0.0, 8.0), 0.0);
    }
}
