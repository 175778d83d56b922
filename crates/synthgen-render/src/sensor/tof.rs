//! Kinect / time-of-flight style depth: axial noise growing with depth and with the angle of
//! incidence (Nguyen, Izadi and Lovell 2012), lateral jitter, flying pixels at edges, range
//! limits.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use synthgen_core::scene::TofSpec;
use synthgen_core::Intrinsics;

use synthgen_core::depth_features::{discontinuities, incidence_cos};

use super::{quantize, Normal};

/// Axial σ in metres at depth `z_m` and incidence angle `theta_rad`.
pub fn tof_sigma_m(spec: &TofSpec, z_m: f64, theta_rad: f64) -> f64 {
    let half_pi = std::f64::consts::FRAC_PI_2;
    let a = (z_m - spec.sigma_z0_m).powi(2);
    let t = theta_rad.min(half_pi - 1e-3);
    spec.sigma_a_m
        + spec.sigma_b_per_m * a
        + spec.sigma_angle_m / z_m.sqrt() * t * t / ((half_pi - t) * (half_pi - t))
}

/// Applies the ToF model to `depth` (metres, row-major, 0 = no hit) in place.
///
/// In order, all from the clean depth: the incidence angle from the normal of the
/// back-projected neighbours (central differences where both neighbours lie on the same
/// surface, else one-sided, else 0); pixels beyond `max_incidence_deg` become 0; a pixel takes
/// a random 4-neighbour's depth with probability `lateral_jitter`; a discontinuity pixel
/// becomes a flying pixel (uniform mix of the nearest and farthest depth around it) with
/// probability `flying_pixel_prob`; Gaussian axial noise `tof_sigma_m`; rounding to
/// `depth_unit_m`; 0 outside `range_m`.
pub fn apply_tof(spec: &TofSpec, k: &Intrinsics, depth: &mut [f32], rng: &mut ChaCha8Rng) {
    let (w, h) = (k.width as usize, k.height as usize);
    if depth.len() != w * h {
        return;
    }
    let clean = depth.to_vec();
    let edges = discontinuities(&clean, w, h, spec.edge_jump_rel as f32);
    let cos_max = spec.max_incidence_deg.to_radians().cos();
    let [lo, hi] = spec.range_m;
    let mut normal = Normal::new();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let z = f64::from(clean[i]);
            if z <= 0.0 {
                continue;
            }
            // Draws in a fixed order per pixel, each only where it is used (the direction
            // for a jittered pixel, the flying mix for an edge pixel).
            let n = normal.sample(rng);
            let u_jitter: f64 = rng.gen();
            // The closed-form cosine (f32); the angle only for the pixels kept.
            let cos = incidence_cos(&clean, spec.edge_jump_rel as f32, k, x, y);
            if f64::from(cos) < cos_max {
                depth[i] = 0.0;
                continue;
            }
            let theta = f64::from(acos_unit(cos));
            let mut zi = z;
            if u_jitter < spec.lateral_jitter {
                let dir: u32 = rng.gen_range(0..4);
                let (nx, ny) = match dir {
                    0 => (x.wrapping_sub(1), y),
                    1 => (x + 1, y),
                    2 => (x, y.wrapping_sub(1)),
                    _ => (x, y + 1),
                };
                if nx < w && ny < h && clean[ny * w + nx] > 0.0 {
                    zi = f64::from(clean[ny * w + nx]);
                }
            }
            if edges[i] && rng.gen::<f64>() < spec.flying_pixel_prob {
                let (zmin, zmax) = neighbour_extent(&clean, w, h, x, y);
                zi = zmin + rng.gen::<f64>() * (zmax - zmin);
            }
            let zn = quantize(zi + tof_sigma_m(spec, zi, theta) * n, spec.depth_unit_m);
            depth[i] = if zn >= lo && zn <= hi { zn as f32 } else { 0.0 };
        }
    }
}

/// acos of `c` in [0, 1] (Abramowitz and Stegun 4.4.46: √(1 − c) times a 7th-degree
/// polynomial in f64, |error| ≤ 2e-8 rad), a few times cheaper than libm's.
#[inline]
fn acos_unit(c: f32) -> f32 {
    let c = f64::from(c.clamp(0.0, 1.0));
    let p = -0.001_262_491_1f64;
    let p = p * c + 0.006_670_090_1;
    let p = p * c - 0.017_088_125_6;
    let p = p * c + 0.030_891_881_0;
    let p = p * c - 0.050_174_304_6;
    let p = p * c + 0.088_978_987_4;
    let p = p * c - 0.214_598_801_6;
    let p = p * c + 1.570_796_305_0;
    ((1.0 - c).sqrt() * p) as f32
}

/// Nearest and farthest non-empty depth among the pixel and its 4-neighbours.
fn neighbour_extent(d: &[f32], w: usize, h: usize, x: usize, y: usize) -> (f64, f64) {
    let mut lo = f64::from(d[y * w + x]);
    let mut hi = lo;
    for (nx, ny) in [
        (x.wrapping_sub(1), y),
        (x + 1, y),
        (x, y.wrapping_sub(1)),
        (x, y + 1),
    ] {
        if nx < w && ny < h {
            let z = f64::from(d[ny * w + nx]);
            if z > 0.0 {
                lo = lo.min(z);
                hi = hi.max(z);
            }
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::acos_unit;

    #[test]
    fn the_polynomial_acos_is_libm_s_to_a_microradian() {
        for i in 0..=10_000 {
            let c = i as f32 / 10_000.0;
            let (got, want) = (acos_unit(c), f64::from(c).acos());
            assert!(
                (f64::from(got) - want).abs() < 1e-6,
                "acos({c}) = {got}, not {want}"
            );
        }
    }
}
