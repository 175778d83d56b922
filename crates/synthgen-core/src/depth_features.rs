//! Per-pixel features of a depth image that depth-sensor models depend on, shared by the
//! models that apply them (`synthgen_render::sensor`) and by the code that fits them to real
//! frames and compares datasets (`synthgen_fit::sensor`): depth discontinuities, the
//! distance to the nearest one, the angle of incidence, the projector's (or a second
//! camera's) shadow, and the brightness of the colour image.
//!
//! Depth images are row-major metres with 0 for "no surface".

use crate::Intrinsics;

/// Marks pixels on a depth discontinuity: a 4-neighbour is empty (0) or differs by more than
/// `rel` times the pixel's depth. Empty pixels and the image border are never marked.
pub fn discontinuities(depth: &[f32], w: usize, h: usize, rel: f32) -> Vec<bool> {
    let mut out = vec![false; w * h];
    if w == 0 || h == 0 {
        return out;
    }
    // A neighbour outside the image never counts: an "up" row of copies of the pixel's own
    // row compares equal. Branch-free per row, so it vectorizes.
    for y in 0..h {
        let row = &depth[y * w..(y + 1) * w];
        let up = if y > 0 {
            &depth[(y - 1) * w..y * w]
        } else {
            row
        };
        let down = if y + 1 < h {
            &depth[(y + 1) * w..(y + 2) * w]
        } else {
            row
        };
        let dst = &mut out[y * w..(y + 1) * w];
        let jump = |n: f32, z: f32| (n <= 0.0) | ((n - z).abs() > rel * z);
        for x in 0..w {
            let z = row[x];
            let l = if x > 0 { row[x - 1] } else { z };
            let r = if x + 1 < w { row[x + 1] } else { z };
            dst[x] = (z > 0.0) & (jump(l, z) | jump(r, z) | jump(up[x], z) | jump(down[x], z));
        }
    }
    out
}

/// Chessboard distance (pixels, 8-connected) from every pixel to the nearest marked one,
/// capped at `cap`: marked pixels are 0, pixels `cap` or more away are `cap`. A breadth-first
/// search from the marked pixels, so the cost grows with the band within `cap`, not with the
/// image.
pub fn edge_distance(marked: &[bool], w: usize, h: usize, cap: u8) -> Vec<u8> {
    let mut dist = vec![cap; w * h];
    let mut front: Vec<usize> = Vec::new();
    for (i, &m) in marked.iter().enumerate() {
        if m {
            dist[i] = 0;
            front.push(i);
        }
    }
    let mut next = Vec::new();
    for d in 1..cap {
        if front.is_empty() {
            break;
        }
        for &i in &front {
            let (x, y) = (i % w, i / w);
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let (y0, y1) = (y.saturating_sub(1), (y + 1).min(h - 1));
            for ny in y0..=y1 {
                for nx in x0..=x1 {
                    let j = ny * w + nx;
                    if dist[j] > d {
                        dist[j] = d;
                        next.push(j);
                    }
                }
            }
        }
        std::mem::swap(&mut front, &mut next);
        next.clear();
    }
    dist
}

/// Angle between the surface normal and the viewing ray at pixel (x, y), radians; 0 for an
/// empty pixel or one whose surface has no usable neighbour. The normal comes from the
/// back-projected 4-neighbours on the same surface (within `rel` of its depth): central
/// differences where both are, else one-sided.
pub fn incidence(d: &[f32], rel: f64, k: &Intrinsics, x: usize, y: usize) -> f64 {
    let (w, h) = (k.width as usize, k.height as usize);
    let point = |x: usize, y: usize| -> Option<[f64; 3]> {
        let z = f64::from(d[y * w + x]);
        (z > 0.0).then(|| {
            [
                (x as f64 - k.cx) / k.fx * z,
                (y as f64 - k.cy) / k.fy * z,
                z,
            ]
        })
    };
    let Some(p) = point(x, y) else {
        return 0.0;
    };
    // A neighbour across a discontinuity is another surface: leave it out.
    let usable = |nx: usize, ny: usize| {
        let zn = f64::from(d[ny * w + nx]);
        zn > 0.0 && (zn - p[2]).abs() <= rel * p[2]
    };
    let diff = |a: Option<[f64; 3]>, b: Option<[f64; 3]>| match (a, b) {
        (Some(a), Some(b)) => Some([b[0] - a[0], b[1] - a[1], b[2] - a[2]]),
        _ => None,
    };
    let left = (x > 0 && usable(x - 1, y))
        .then(|| point(x - 1, y))
        .flatten();
    let right = (x + 1 < w && usable(x + 1, y))
        .then(|| point(x + 1, y))
        .flatten();
    let up = (y > 0 && usable(x, y - 1))
        .then(|| point(x, y - 1))
        .flatten();
    let down = (y + 1 < h && usable(x, y + 1))
        .then(|| point(x, y + 1))
        .flatten();
    let du = diff(left, right)
        .or_else(|| diff(Some(p), right))
        .or_else(|| diff(left, Some(p)));
    let dv = diff(up, down)
        .or_else(|| diff(Some(p), down))
        .or_else(|| diff(up, Some(p)));
    let (Some(a), Some(b)) = (du, dv) else {
        return 0.0;
    };
    let n = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let nn = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let pn = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    if nn <= 0.0 || pn <= 0.0 {
        return 0.0;
    }
    let c = ((n[0] * p[0] + n[1] * p[1] + n[2] * p[2]) / (nn * pn)).abs();
    c.min(1.0).acos()
}

/// Cosine of the angle of incidence at pixel (x, y) from the depth's derivatives: with
/// z_u, z_v the depth differences to the neighbours on the same surface (within `rel` of its
/// depth; central where both are, else one-sided, else 0) and r = ((u − cx)/fx, (v − cy)/fy, 1)
/// the ray, the surface normal is n = (−A, −B, A r_x + B r_y + C) with A = z z_u / fy,
/// B = z z_v / fx, C = z² / (fx fy), and cos θ = C / (|n| |r|). 1 for an empty pixel. The
/// closed form of [`incidence`]'s cross product, a few times cheaper; what the
/// structured-light model and its fit use.
#[inline]
pub fn incidence_cos(d: &[f32], rel: f32, k: &Intrinsics, x: usize, y: usize) -> f32 {
    let Some(NormalTerms { a, b, c, rx, ry }) = normal_terms(d, rel, k, x, y) else {
        return 1.0;
    };
    let nz = a * rx + b * ry + c;
    let nn = (a * a + b * b + nz * nz).sqrt();
    let rn = (rx * rx + ry * ry + 1.0).sqrt();
    if nn <= 0.0 {
        return 1.0;
    }
    (c / (nn * rn)).clamp(0.0, 1.0)
}

/// The unit surface normal at pixel (x, y) in camera coordinates, turned towards the camera:
/// [`incidence_cos`]'s n = (−A, −B, A r_x + B r_y + C), negated. None for an empty pixel.
#[inline]
pub fn normal_cam(d: &[f32], rel: f32, k: &Intrinsics, x: usize, y: usize) -> Option<glam::Vec3> {
    let NormalTerms { a, b, c, rx, ry } = normal_terms(d, rel, k, x, y)?;
    glam::Vec3::new(a, b, -(a * rx + b * ry + c)).try_normalize()
}

/// The terms of the normal from the depth's derivatives at (x, y) (see [`incidence_cos`]).
struct NormalTerms {
    a: f32,
    b: f32,
    c: f32,
    rx: f32,
    ry: f32,
}

#[inline(always)]
fn normal_terms(d: &[f32], rel: f32, k: &Intrinsics, x: usize, y: usize) -> Option<NormalTerms> {
    let (w, h) = (k.width as usize, k.height as usize);
    let i = y * w + x;
    let z = d[i];
    if z <= 0.0 {
        return None;
    }
    let lim = rel * z;
    let same = |j: usize| {
        let n = d[j];
        if n > 0.0 && (n - z).abs() <= lim {
            Some(n)
        } else {
            None
        }
    };
    let slope = |lo: Option<f32>, hi: Option<f32>| match (lo, hi) {
        (Some(a), Some(b)) => 0.5 * (b - a),
        (None, Some(b)) => b - z,
        (Some(a), None) => z - a,
        (None, None) => 0.0,
    };
    let zu = slope(
        if x > 0 { same(i - 1) } else { None },
        if x + 1 < w { same(i + 1) } else { None },
    );
    let zv = slope(
        if y > 0 { same(i - w) } else { None },
        if y + 1 < h { same(i + w) } else { None },
    );
    let (fx, fy) = (k.fx as f32, k.fy as f32);
    Some(NormalTerms {
        a: z * zu / fy,
        b: z * zv / fx,
        c: z * z / (fx * fy),
        rx: (x as f32 - k.cx as f32) / fx,
        ry: (y as f32 - k.cy as f32) / fy,
    })
}

/// Angle of incidence, degrees, of every pixel (0 where empty): [`incidence_cos`] over the
/// image.
pub fn incidence_map_deg(d: &[f32], rel: f32, k: &Intrinsics) -> Vec<f32> {
    let (w, h) = (k.width as usize, k.height as usize);
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            if d[y * w + x] > 0.0 {
                out[y * w + x] = incidence_cos(d, rel, k, x, y).acos().to_degrees();
            }
        }
    }
    out
}

/// Pixels that a second viewpoint at `offset_px_m` = f · b along the camera's x axis cannot
/// see (f: focal length in pixels, b: the signed offset in metres): the shadow of a
/// projector, or the occlusion of a stereo partner.
///
/// A point at column u and depth z lies at u − f b / z as the second viewpoint sees it (its
/// "column" there). Scanning a row away from the viewpoint's side, a point is hidden when a
/// point already passed (nearer the viewpoint's side) lands at or beyond it: a closer surface
/// is in the way. So with b > 0 (viewpoint to the right) the shadow lies on the left of every
/// foreground object, with b < 0 on the right. With `outside` the points that fall outside
/// the second view (column < −0.5 or ≥ width) are hidden too, as for a stereo camera of the
/// same field of view; a projector lights a wider field, so pass false for it.
pub fn viewpoint_shadow(
    depth: &[f32],
    w: usize,
    h: usize,
    offset_px_m: f64,
    outside: bool,
) -> Vec<bool> {
    viewpoint_shadows(depth, w, h, &[offset_px_m], outside)
}

/// SplitMix64's finalizer: a good 64-bit mix of a counter.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A uniform random field on `w` x `h` pixels whose values are correlated over about `size`
/// pixels: standard normals on a grid of spacing `size` (from `seed`), bilinearly
/// interpolated, divided by the interpolation's own standard deviation (so every pixel is
/// exactly standard normal), through the normal CDF. So `field < p` marks a share p of the
/// pixels, in blobs about `size` wide. `size` ≤ 1: independent pixels.
pub fn smooth_uniform_field(w: usize, h: usize, size: f64, seed: u64) -> Vec<f32> {
    let cdf = normal_cdf_table();
    let normal = |i: u64| -> f32 {
        // Irwin–Hall sum of four 16-bit uniforms, centred and scaled.
        let b = mix64(seed.wrapping_add(i.wrapping_mul(0x9e37_79b9_7f4a_7c15)));
        let s = (b & 0xffff) + ((b >> 16) & 0xffff) + ((b >> 32) & 0xffff) + (b >> 48);
        (((s as f64 + 2.0) / 65_536.0 - 2.0) * 3f64.sqrt()) as f32
    };
    let phi = |g: f32| -> f32 {
        let t =
            ((g + CDF_RANGE) * (CDF_STEPS as f32 / (2.0 * CDF_RANGE))).clamp(0.0, CDF_STEPS as f32);
        cdf[t as usize]
    };
    if size <= 1.0 {
        return (0..w * h).map(|i| phi(normal(i as u64))).collect();
    }
    let s = size as f32;
    let gw = (w as f32 / s).ceil() as usize + 2;
    let gh = (h as f32 / s).ceil() as usize + 2;
    let grid: Vec<f32> = (0..gw * gh).map(|i| normal(i as u64)).collect();
    // Per column: grid index, weight and 1 / the interpolation's spread along x (the
    // bilinear weights' squares sum to a product of an x and a y factor); per row the same.
    let spread = |f: f32| ((1.0 - f) * (1.0 - f) + f * f).sqrt();
    let cols: Vec<(usize, f32, f32)> = (0..w)
        .map(|x| {
            let g = x as f32 / s;
            let f = g - g.floor();
            (g as usize, f, 1.0 / spread(f))
        })
        .collect();
    // Each grid row interpolated along x once (and divided by the x spread), then every image
    // row is a blend of two of those.
    let along_x = |gy: usize| -> Vec<f32> {
        let r = &grid[gy * gw..(gy + 1) * gw];
        cols.iter()
            .map(|&(gx, fx, inv_sx)| ((1.0 - fx) * r[gx] + fx * r[gx + 1]) * inv_sx)
            .collect()
    };
    let mut out = vec![0f32; w * h];
    let (mut top_at, mut top, mut bottom) = (0usize, along_x(0), along_x(1));
    for y in 0..h {
        let g = y as f32 / s;
        let (gy, fy) = (g as usize, g - g.floor());
        if gy != top_at {
            top = if gy == top_at + 1 {
                std::mem::take(&mut bottom)
            } else {
                along_x(gy)
            };
            bottom = along_x(gy + 1);
            top_at = gy;
        }
        let inv_sy = 1.0 / spread(fy);
        let (a, b) = ((1.0 - fy) * inv_sy, fy * inv_sy);
        for ((o, &t), &u) in out[y * w..(y + 1) * w].iter_mut().zip(&top).zip(&bottom) {
            *o = phi(a * t + b * u);
        }
    }
    out
}

const CDF_STEPS: usize = 4096;
const CDF_RANGE: f32 = 6.0;

/// The standard normal CDF on [−6, 6] in 4096 steps.
fn normal_cdf_table() -> &'static [f32] {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=CDF_STEPS)
            .map(|i| {
                let x = -f64::from(CDF_RANGE)
                    + 2.0 * f64::from(CDF_RANGE) * i as f64 / CDF_STEPS as f64;
                (0.5 * erfc(-x / std::f64::consts::SQRT_2)) as f32
            })
            .collect()
    })
}

/// The complementary error function (Numerical Recipes' erfc, |error| < 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Mean length (pixels) of the horizontal runs of `field < p`: how blob-like the holes a
/// field makes are (what `sensor fit` matches `hole_size_px` with).
pub fn mean_run_below(field: &[f32], w: usize, p: f32) -> f64 {
    let (mut runs, mut px) = (0u64, 0u64);
    for row in field.chunks_exact(w.max(1)) {
        let mut inside = false;
        for &v in row {
            let hole = v < p;
            if hole {
                px += 1;
                if !inside {
                    runs += 1;
                }
            }
            inside = hole;
        }
    }
    if runs == 0 {
        0.0
    } else {
        px as f64 / runs as f64
    }
}

/// The union of [`viewpoint_shadow`]s of several offsets (a projector and a second camera),
/// from one reciprocal of the depth per pixel.
pub fn viewpoint_shadows(
    depth: &[f32],
    w: usize,
    h: usize,
    offsets_px_m: &[f64],
    outside: bool,
) -> Vec<bool> {
    let mut out = vec![false; w * h];
    if w == 0 {
        return out;
    }
    let wf = w as f32;
    let mut inv = vec![0f32; w];
    let mut col = vec![0f32; w];
    for y in 0..h {
        let row = &depth[y * w..(y + 1) * w];
        let dst = &mut out[y * w..(y + 1) * w];
        for (v, &z) in inv.iter_mut().zip(row) {
            *v = 1.0 / z.max(1e-6);
        }
        for &offset in offsets_px_m.iter().filter(|o| **o != 0.0) {
            let off = offset as f32;
            for (x, (c, &v)) in col.iter_mut().zip(&inv).enumerate() {
                *c = x as f32 - off * v;
            }
            let hidden = |ur: f32, seen: bool| seen | (outside & ((ur < -0.5) | (ur >= wf - 0.5)));
            if offset > 0.0 {
                let mut min_r = f32::INFINITY;
                for x in (0..w).rev() {
                    if row[x] <= 0.0 {
                        continue;
                    }
                    let ur = col[x];
                    dst[x] |= hidden(ur, ur >= min_r);
                    min_r = min_r.min(ur);
                }
            } else {
                let mut max_r = f32::NEG_INFINITY;
                for x in 0..w {
                    if row[x] <= 0.0 {
                        continue;
                    }
                    let ur = col[x];
                    dst[x] |= hidden(ur, ur <= max_r);
                    max_r = max_r.max(ur);
                }
            }
        }
    }
    out
}

/// Brightness of an 8-bit sRGB pixel in 0..1: Rec. 709 weights on the encoded values (what
/// the fit measures on real images and the model reads from rendered ones).
#[inline]
pub fn luminance(rgb: [u8; 3]) -> f32 {
    (0.2126 * f32::from(rgb[0]) + 0.7152 * f32::from(rgb[1]) + 0.0722 * f32::from(rgb[2])) / 255.0
}

/// [`luminance`] of every pixel of a row-major RGB buffer.
pub fn luminance_map(rgb: &[u8]) -> Vec<f32> {
    rgb.chunks_exact(3)
        .map(|p| luminance([p[0], p[1], p[2]]))
        .collect()
}

#[cfg(test)]
mod tests {

    /// A tilted plane's depth gives its normal back, turned towards the camera; an empty
    /// pixel has none.
    #[test]
    fn normal_cam_of_a_tilted_plane() {
        let k = Intrinsics {
            width: 20,
            height: 20,
            fx: 50.0,
            fy: 50.0,
            cx: 10.0,
            cy: 10.0,
        };
        // The plane z = 1 + 0.5 x (camera coordinates): normal ∝ (0.5, 0, −1).
        let mut d = vec![0.0f32; 400];
        for y in 0..20 {
            for x in 0..20 {
                d[y * 20 + x] = 1.0 / (1.0 - 0.5 * (x as f32 - 10.0) / 50.0);
            }
        }
        let n = normal_cam(&d, 0.05, &k, 10, 10).unwrap();
        let want = glam::Vec3::new(0.5, 0.0, -1.0).normalize();
        assert!(n.dot(want) > 0.999, "{n}");
        d[0] = 0.0;
        assert!(normal_cam(&d, 0.05, &k, 0, 0).is_none());
    }

    use super::*;

    #[test]
    fn distance_grows_away_from_marks_and_is_capped() {
        let (w, h) = (9, 5);
        let mut m = vec![false; w * h];
        m[2 * w + 4] = true;
        let d = edge_distance(&m, w, h, 3);
        assert_eq!(d[2 * w + 4], 0);
        assert_eq!(d[2 * w + 5], 1);
        assert_eq!(d[w + 3], 1);
        assert_eq!(d[2 * w + 6], 2);
        assert_eq!(d[2 * w + 7], 3);
        assert_eq!(d[2 * w + 8], 3);
        assert!(edge_distance(&vec![false; w * h], w, h, 7)
            .iter()
            .all(|&v| v == 7));
    }

    #[test]
    fn smooth_field_is_uniform_and_blobby() {
        let (w, h) = (300, 200);
        for size in [1.0, 3.0, 6.0] {
            let f = smooth_uniform_field(w, h, size, 7);
            let share = f.iter().filter(|&&v| v < 0.1).count() as f64 / f.len() as f64;
            assert!((share - 0.1).abs() < 0.02, "size {size}: {share}");
            let mean = f.iter().map(|&v| f64::from(v)).sum::<f64>() / f.len() as f64;
            assert!((mean - 0.5).abs() < 0.03, "size {size}: mean {mean}");
        }
        let runs = |size| mean_run_below(&smooth_uniform_field(w, h, size, 3), w, 0.1);
        assert!(runs(1.0) < 1.3, "{}", runs(1.0));
        assert!(runs(3.0) > runs(1.0) + 0.5 && runs(6.0) > runs(3.0) + 0.5);
        assert_eq!(
            smooth_uniform_field(50, 40, 3.0, 1),
            smooth_uniform_field(50, 40, 3.0, 1)
        );
        assert_ne!(
            smooth_uniform_field(50, 40, 3.0, 1),
            smooth_uniform_field(50, 40, 3.0, 2)
        );
    }

    #[test]
    fn shadow_side_follows_the_sign_of_the_offset() {
        // A wall at 2 m with a box at 1 m over columns 30..40; f b = 20 px·m.
        let (w, h) = (80usize, 1usize);
        let mut d = vec![2.0f32; w];
        for v in &mut d[30..40] {
            *v = 1.0;
        }
        // Shadow width f b (1/z_f − 1/z_b) = 20 · 0.5 = 10 px.
        let right = viewpoint_shadow(&d, w, h, 20.0, false);
        let shadowed: Vec<usize> = (0..w).filter(|&x| right[x]).collect();
        assert_eq!(
            shadowed,
            (20..30).collect::<Vec<_>>(),
            "viewpoint right → shadow left"
        );
        let left = viewpoint_shadow(&d, w, h, -20.0, false);
        let shadowed: Vec<usize> = (0..w).filter(|&x| left[x]).collect();
        assert_eq!(
            shadowed,
            (40..50).collect::<Vec<_>>(),
            "viewpoint left → shadow right"
        );
        // The box itself is always seen.
        assert!((30..40).all(|x| !right[x] && !left[x]));
        assert!(viewpoint_shadow(&d, w, h, 0.0, true).iter().all(|s| !s));
    }

    #[test]
    fn incidence_of_a_tilted_plane() {
        let k = Intrinsics {
            width: 64,
            height: 48,
            fx: 100.0,
            fy: 100.0,
            cx: 31.5,
            cy: 23.5,
        };
        // Plane z = 1 + 0.5·X (tilted about y): normal (−0.5, 0, 1); at the centre the ray is
        // (0, 0, 1) so the angle is atan(0.5).
        let (w, h) = (64usize, 48usize);
        let mut d = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let u = (x as f64 - k.cx) / k.fx;
                d[y * w + x] = (1.0 / (1.0 - 0.5 * u)) as f32;
            }
        }
        let want = 0.5f64.atan().to_degrees();
        let a = incidence(&d, 0.05, &k, 32, 24).to_degrees();
        assert!((a - want).abs() < 1.0, "{a} vs {want}");
        let b = f64::from(incidence_cos(&d, 0.05, &k, 32, 24))
            .acos()
            .to_degrees();
        assert!((b - want).abs() < 1.0, "{b} vs {want}");
        // Off-centre the two agree as well (the ray is not the optical axis there).
        for (x, y) in [(5, 5), (60, 40), (10, 44)] {
            let a = incidence(&d, 0.05, &k, x, y).to_degrees();
            let b = f64::from(incidence_cos(&d, 0.05, &k, x, y))
                .acos()
                .to_degrees();
            assert!((a - b).abs() < 0.5, "({x}, {y}): {a} vs {b}");
        }
    }
}
