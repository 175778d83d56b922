//! The BOP 2019 pose-error functions, as bop_toolkit's `pose_error.py` and `misc.py` define
//! them: MSSD and MSPD over an object's symmetry transformations (continuous symmetries
//! discretized), and VSD over depth images. Everything is in millimetres and pixels, in f64,
//! on the numbers of the files (rotations are used as stored, approximate or not).

use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::{DepthWindowMm, Symmetries};

pub use crate::results::RawPose;

/// One symmetry transformation of a model: `p -> r p + t` (t in mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SymTransform {
    pub r: DMat3,
    pub t_mm: DVec3,
}

/// bop_toolkit's `transform.rotation_matrix(angle, axis)` (3x3 part): the axis is normalized,
/// then `cos I + (1 - cos) d dᵀ + sin [d]×`.
fn axis_angle(angle: f64, axis: [f64; 3]) -> DMat3 {
    let a = DVec3::from_array(axis);
    let d = a / a.dot(a).sqrt();
    let (s, c) = (angle.sin(), angle.cos());
    let ds = d * s;
    // Rows of the matrix, assembled column-major.
    let row = |i: usize| -> [f64; 3] {
        let mut r = [0.0; 3];
        for (j, v) in r.iter_mut().enumerate() {
            *v = (if i == j { c } else { 0.0 }) + d[i] * d[j] * (1.0 - c);
        }
        r
    };
    let (r0, r1, r2) = (row(0), row(1), row(2));
    DMat3::from_cols(
        DVec3::new(r0[0], r1[0] + ds.z, r2[0] - ds.y),
        DVec3::new(r0[1] - ds.z, r1[1], r2[1] + ds.x),
        DVec3::new(r0[2] + ds.y, r1[2] - ds.x, r2[2]),
    )
}

/// The symmetry transformations of a model, as bop_toolkit's
/// `misc.get_symmetry_transformations(model_info, max_sym_disc_step)`: the identity and the
/// discrete symmetries, each combined with every step of each continuous symmetry
/// discretized into `ceil(π / max_sym_disc_step)` rotations about its axis and offset.
pub fn symmetry_transformations(sym: &Symmetries, max_sym_disc_step: f64) -> Vec<SymTransform> {
    let mut disc = vec![SymTransform {
        r: DMat3::IDENTITY,
        t_mm: DVec3::ZERO,
    }];
    for m in &sym.symmetries_discrete {
        disc.push(SymTransform {
            r: DMat3::from_cols(
                DVec3::new(m[0], m[4], m[8]),
                DVec3::new(m[1], m[5], m[9]),
                DVec3::new(m[2], m[6], m[10]),
            ),
            t_mm: DVec3::new(m[3], m[7], m[11]),
        });
    }
    let mut cont = Vec::new();
    for c in &sym.symmetries_continuous {
        let offset = DVec3::from_array(c.offset);
        let steps = (std::f64::consts::PI / max_sym_disc_step).ceil() as usize;
        let step = 2.0 * std::f64::consts::PI / steps as f64;
        for i in 0..steps {
            let r = axis_angle(i as f64 * step, c.axis);
            cont.push(SymTransform {
                r,
                t_mm: -(r * offset) + offset,
            });
        }
    }
    if cont.is_empty() {
        return disc;
    }
    let mut out = Vec::with_capacity(disc.len() * cont.len());
    for d in &disc {
        for c in &cont {
            out.push(SymTransform {
                r: c.r * d.r,
                t_mm: c.r * d.t_mm + c.t_mm,
            });
        }
    }
    out
}

/// `gt ∘ sym`: the GT pose moved by a symmetry of the model.
#[inline(always)]
fn gt_sym(gt: &RawPose, s: &SymTransform) -> RawPose {
    RawPose {
        r: gt.r * s.r,
        t_mm: gt.r * s.t_mm + gt.t_mm,
    }
}

/// Minimum over symmetries of the maximum over points of `dist(point)`: symmetries whose
/// running maximum already exceeds the best are abandoned (the result is the same).
fn min_max<F: Fn(&RawPose, DVec3) -> f64>(
    syms: &[SymTransform],
    gt: &RawPose,
    pts: &[DVec3],
    dist: F,
) -> f64 {
    let mut best = f64::INFINITY;
    for s in syms {
        let g = gt_sym(gt, s);
        let mut worst = 0.0f64;
        for &p in pts {
            let d = dist(&g, p);
            if d > worst {
                worst = d;
                if worst >= best {
                    break;
                }
            }
        }
        if worst < best {
            best = worst;
        }
    }
    best
}

/// Maximum Symmetry-aware Surface Distance (mm): bop_toolkit's `pose_error.mssd`.
pub fn mssd(est: &RawPose, gt: &RawPose, pts_mm: &[DVec3], syms: &[SymTransform]) -> f64 {
    min_max(syms, gt, pts_mm, |g, p| {
        (est.apply(p) - g.apply(p)).length()
    })
}

/// Camera intrinsics as a 3x3 matrix (row-major `cam_K`).
pub fn k_matrix(cam_k: &[f64; 9]) -> DMat3 {
    let k = cam_k;
    DMat3::from_cols(
        DVec3::new(k[0], k[3], k[6]),
        DVec3::new(k[1], k[4], k[7]),
        DVec3::new(k[2], k[5], k[8]),
    )
}

#[inline(always)]
fn project(k: &DMat3, pose: &RawPose, p: DVec3) -> (f64, f64) {
    let q = *k * pose.apply(p);
    (q.x / q.z, q.y / q.z)
}

/// Maximum Symmetry-aware Projection Distance (px): bop_toolkit's `pose_error.mspd`.
pub fn mspd(
    est: &RawPose,
    gt: &RawPose,
    k: &DMat3,
    pts_mm: &[DVec3],
    syms: &[SymTransform],
) -> f64 {
    min_max(syms, gt, pts_mm, |g, p| {
        let (ex, ey) = project(k, est, p);
        let (gx, gy) = project(k, g, p);
        ((ex - gx).powi(2) + (ey - gy).powi(2)).sqrt()
    })
}

/// bop_toolkit's `misc.overlapping_sphere_projections`: whether the image discs of two spheres
/// of `radius` centred at `p1`, `p2` (mm) overlap, approximately. VSD is 1 when they do not.
pub fn overlapping_sphere_projections(radius: f64, p1: DVec3, p2: DVec3) -> bool {
    if p1.z == 0.0 || p2.z == 0.0 {
        return false;
    }
    let (a, b) = (p1 / p1.z, p2 / p2.z);
    let d = ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt();
    d < radius * (1.0 / p1.z + 1.0 / p2.z)
}

/// The corners of the axis-aligned box of `pts` as bop_toolkit's renderers compute them
/// (`misc.calc_3d_bbox`: minimum, then minimum + size), in its order.
pub fn bbox_corners(pts: &[DVec3]) -> [DVec3; 8] {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in pts {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let size = hi - lo;
    let mut out = [DVec3::ZERO; 8];
    let mut n = 0;
    for i in 0..2 {
        for j in 0..2 {
            for k in 0..2 {
                out[n] = DVec3::new(
                    if i == 0 { lo.x } else { lo.x + size.x },
                    if j == 0 { lo.y } else { lo.y + size.y },
                    if k == 0 { lo.z } else { lo.z + size.z },
                );
                n += 1;
            }
        }
    }
    out
}

/// Turns an exact depth render into what bop_toolkit's default renderer (vispy) returns for
/// the same pose: its near and far planes are the nearest and farthest corner of the model's
/// box (from the pose in float32), the depth buffer holds 16 bits between them
/// (GL_DEPTH_COMPONENT16, rounded), and the read-back is converted to millimetres in float32.
/// A value that lands on the far plane reads as background. This quantizes the depth to
/// about a micrometre per step; VSD's pixel tests (δ, τ) see these values.
pub fn quantize_like_vispy(out: &mut DepthWindowMm, r: &DMat3, t_mm: DVec3, corners: &[DVec3; 8]) {
    // mat_view_cv is float32: row 2 of [R | t].
    let row = [
        r.x_axis.z as f32 as f64,
        r.y_axis.z as f32 as f64,
        r.z_axis.z as f32 as f64,
        t_mm.z as f32 as f64,
    ];
    let (mut near, mut far) = (f64::INFINITY, f64::NEG_INFINITY);
    for c in corners {
        let z = row[0] * c.x + row[1] * c.y + row[2] * c.z + row[3];
        near = near.min(z);
        far = far.max(z);
    }
    if far <= near {
        return;
    }
    let mult = ((near * far) / (near - far)) as f32;
    let addi = (far / (near - far)) as f32;
    for d in out.depth_mm.iter_mut() {
        if *d <= 0.0 {
            continue;
        }
        let z = *d as f64;
        let zw = far / (far - near) * (1.0 - near / z);
        let q = (zw * 65535.0).round().clamp(0.0, 65535.0);
        *d = if q >= 65535.0 {
            0.0
        } else {
            mult / ((q / 65535.0) as f32 + addi)
        };
    }
}

/// A test depth image in millimetres, as bop_toolkit reads it: `float32(raw) * float32(scale)`.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMm {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl DepthMm {
    /// From a uint16 depth PNG's values and `depth_scale` (mm per unit).
    pub fn from_raw(width: u32, height: u32, raw: &[u16], depth_scale: f64) -> DepthMm {
        let s = depth_scale as f32;
        DepthMm {
            width,
            height,
            data: raw.iter().map(|&v| v as f32 * s).collect(),
        }
    }
}

/// Per-pixel factors `(x - cx) / fx` and `(y - cy) / fy` of the depth-to-distance conversion
/// (bop_toolkit's `depth_im_to_dist_im_fast`).
#[derive(Debug, Clone)]
pub struct DistFactors {
    xs: Vec<f64>,
    ys: Vec<f64>,
}

impl DistFactors {
    pub fn new(cam_k: &[f64; 9], width: u32, height: u32) -> DistFactors {
        let (fx, cx, fy, cy) = (cam_k[0], cam_k[2], cam_k[4], cam_k[5]);
        DistFactors {
            xs: (0..width).map(|x| (x as f64 - cx) / fx).collect(),
            ys: (0..height).map(|y| (y as f64 - cy) / fy).collect(),
        }
    }

    /// Distance from the camera centre of the point with depth `d` (mm) at pixel (x, y).
    #[inline(always)]
    fn dist(&self, x: usize, y: usize, d: f32) -> f64 {
        let d = d as f64;
        ((self.xs[x] * d).powi(2) + (self.ys[y] * d).powi(2) + d.powi(2)).sqrt()
    }
}

/// Visible Surface Discrepancy ("step" cost, "bop19" visibility), one value per tau:
/// bop_toolkit's `pose_error.vsd` given the two rendered depths (`est`, `gt`) and the
/// test depth (mm). `taus` are fractions of `diameter_mm` when `normalized_by_diameter`.
#[allow(clippy::too_many_arguments)]
pub fn vsd(
    est: &DepthWindowMm,
    gt: &DepthWindowMm,
    test: &DepthMm,
    factors: &DistFactors,
    delta_mm: f64,
    taus: &[f64],
    normalized_by_diameter: bool,
    diameter_mm: f64,
) -> Vec<f64> {
    let delta = delta_mm as f32;
    // Only pixels covered by one of the renders can be visible.
    let (mut x0, mut y0, mut x1, mut y1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
    for a in [est, gt] {
        if a.width > 0 && a.height > 0 {
            x0 = x0.min(a.x0);
            y0 = y0.min(a.y0);
            x1 = x1.max(a.x0 + a.width as i32);
            y1 = y1.max(a.y0 + a.height as i32);
        }
    }
    let (x0, y0) = (x0.max(0), y0.max(0));
    let (x1, y1) = (x1.min(test.width as i32), y1.min(test.height as i32));
    let mut union = 0usize;
    let mut inter = 0usize;
    let mut costs = vec![0usize; taus.len()];
    let scale = if normalized_by_diameter {
        diameter_mm
    } else {
        1.0
    };
    for y in y0..y1 {
        for x in x0..x1 {
            let dg = gt.at(x, y);
            let de = est.at(x, y);
            if dg <= 0.0 && de <= 0.0 {
                continue;
            }
            let (xu, yu) = (x as usize, y as usize);
            let dt = test.data[yu * test.width as usize + xu];
            let dist_t = factors.dist(xu, yu, dt);
            let visible = |d: f32| -> (bool, f64) {
                if d <= 0.0 {
                    return (false, 0.0);
                }
                let dist = factors.dist(xu, yu, d);
                // bop_toolkit compares in float32.
                let diff = dist as f32 - dist_t as f32;
                (diff <= delta || dist_t == 0.0, dist)
            };
            let (vis_g, dist_g) = visible(dg);
            let (vis_e_raw, dist_e) = visible(de);
            let vis_e = vis_e_raw || (vis_g && de > 0.0);
            if vis_g || vis_e {
                union += 1;
            }
            if vis_g && vis_e {
                inter += 1;
                let d = (dist_g - dist_e).abs() / scale;
                for (c, &tau) in costs.iter_mut().zip(taus) {
                    *c += usize::from(d >= tau);
                }
            }
        }
    }
    if union == 0 {
        return vec![1.0; taus.len()];
    }
    let comp = union - inter;
    costs
        .iter()
        .map(|&c| (c + comp) as f64 / union as f64)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use synthgen_core::symmetry::ContinuousSymmetry;

    fn pose(r: DMat3, t: [f64; 3]) -> RawPose {
        RawPose {
            r,
            t_mm: DVec3::from_array(t),
        }
    }

    #[test]
    fn axis_angle_matches_rodrigues() {
        let r = axis_angle(0.7, [0.0, 0.0, 2.0]);
        let want = DMat3::from_rotation_z(0.7);
        assert!(r.abs_diff_eq(want, 1e-15), "{r:?}");
        let r = axis_angle(1.3, [1.0, -2.0, 0.5]);
        let want = DMat3::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 1.3);
        assert!(r.abs_diff_eq(want, 1e-14));
    }

    #[test]
    fn continuous_symmetry_steps_as_bop_toolkit() {
        let s = Symmetries {
            symmetries_discrete: vec![],
            symmetries_continuous: vec![ContinuousSymmetry {
                axis: [0.0, 0.0, 1.0],
                offset: [0.0, 0.0, 0.0],
            }],
        };
        // ceil(pi / 0.01) = 315 rotations.
        assert_eq!(symmetry_transformations(&s, 0.01).len(), 315);
        let mut s2 = s.clone();
        s2.symmetries_discrete = vec![[
            1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ]];
        assert_eq!(symmetry_transformations(&s2, 0.01).len(), 630);
        assert_eq!(
            symmetry_transformations(&Symmetries::default(), 0.01).len(),
            1
        );
    }

    #[test]
    fn mssd_of_a_rotated_cylinder_is_zero_about_its_axis() {
        // Points on a ring about z: any rotation about z maps the ring onto itself.
        let pts: Vec<DVec3> = (0..36)
            .map(|i| {
                let a = i as f64 * 10f64.to_radians();
                DVec3::new(50.0 * a.cos(), 50.0 * a.sin(), 20.0)
            })
            .collect();
        let s = Symmetries {
            symmetries_discrete: vec![],
            symmetries_continuous: vec![ContinuousSymmetry {
                axis: [0.0, 0.0, 1.0],
                offset: [0.0, 0.0, 0.0],
            }],
        };
        let syms = symmetry_transformations(&s, 0.01);
        let gt = pose(DMat3::IDENTITY, [0.0, 0.0, 800.0]);
        // 40° about z: a symmetry step lands within 2π/315 of it.
        let est = pose(
            DMat3::from_rotation_z(40f64.to_radians()),
            [0.0, 0.0, 800.0],
        );
        let e = mssd(&est, &gt, &pts, &syms);
        let step = 2.0 * std::f64::consts::PI / 315.0;
        assert!(e <= 2.0 * 50.0 * (step / 4.0).sin() + 1e-9, "{e}");
        // Without the symmetry the error is the chord of 40°.
        let e0 = mssd(
            &est,
            &gt,
            &pts,
            &symmetry_transformations(&Symmetries::default(), 0.01),
        );
        assert!(
            (e0 - 2.0 * 50.0 * 20f64.to_radians().sin()).abs() < 1e-9,
            "{e0}"
        );
        // A 5 mm shift is 5 mm.
        let est = pose(DMat3::IDENTITY, [5.0, 0.0, 800.0]);
        assert!((mssd(&est, &gt, &pts, &syms) - 5.0).abs() < 1e-9);
    }

    #[test]
    fn mspd_is_the_largest_pixel_shift() {
        let k = k_matrix(&[600.0, 0.0, 320.0, 0.0, 600.0, 240.0, 0.0, 0.0, 1.0]);
        let pts = vec![DVec3::new(0.0, 0.0, 0.0), DVec3::new(10.0, 0.0, 0.0)];
        let gt = pose(DMat3::IDENTITY, [0.0, 0.0, 600.0]);
        let est = pose(DMat3::IDENTITY, [3.0, 0.0, 600.0]);
        let e = mspd(
            &est,
            &gt,
            &k,
            &pts,
            &[SymTransform {
                r: DMat3::IDENTITY,
                t_mm: DVec3::ZERO,
            }],
        );
        assert!((e - 3.0).abs() < 1e-12, "{e}");
    }

    #[test]
    fn sphere_projection_overlap() {
        let a = DVec3::new(0.0, 0.0, 1000.0);
        assert!(overlapping_sphere_projections(
            50.0,
            a,
            DVec3::new(90.0, 0.0, 1000.0)
        ));
        assert!(!overlapping_sphere_projections(
            50.0,
            a,
            DVec3::new(110.0, 0.0, 1000.0)
        ));
        assert!(!overlapping_sphere_projections(
            50.0,
            a,
            DVec3::new(0.0, 0.0, 0.0)
        ));
    }

    fn window(x0: i32, y0: i32, w: u32, h: u32, d_m: f32) -> DepthWindowMm {
        DepthWindowMm {
            x0,
            y0,
            width: w,
            height: h,
            depth_mm: vec![d_m * 1000.0; (w * h) as usize],
        }
    }

    #[test]
    fn vsd_counts_pixels_as_bop_toolkit() {
        let k = [100.0, 0.0, 5.0, 0.0, 100.0, 5.0, 0.0, 0.0, 1.0];
        let f = DistFactors::new(&k, 10, 10);
        // Test depth: a flat wall at 1 m; no hole.
        let test = DepthMm::from_raw(10, 10, &[1000; 100], 1.0);
        // GT: 4x4 square at 1 m (visible). Estimate: same square shifted by 2 px.
        let gt = window(2, 2, 4, 4, 1.0);
        let est = window(4, 2, 4, 4, 1.0);
        let e = vsd(&est, &gt, &test, &f, 15.0, &[0.05, 0.5], true, 100.0);
        // Union 24 px, intersection 8 with equal depth: (0 + 16) / 24.
        assert_eq!(e, vec![16.0 / 24.0, 16.0 / 24.0]);
        // An estimate 20 mm too far at the same place: the whole overlap, cost 0.2 diameter.
        let est = window(2, 2, 4, 4, 1.02);
        let e = vsd(&est, &gt, &test, &f, 15.0, &[0.05, 0.5], true, 100.0);
        // est at 1.02 m is behind the wall (beyond delta) but visible where the GT is.
        assert!(e[0] > 0.99 && e[1] == 0.0, "{e:?}");
        // Nothing rendered: 1.
        let none = DepthWindowMm::default();
        assert_eq!(
            vsd(&none, &none, &test, &f, 15.0, &[0.1], true, 100.0),
            vec![1.0]
        );
    }
}
