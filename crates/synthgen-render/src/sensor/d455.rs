//! Intel RealSense D455-style active stereo depth.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use synthgen_core::scene::D455Spec;

use synthgen_core::depth_features::{discontinuities, viewpoint_shadow};

use super::{quantize, Normal};

/// Applies the D455 model to `depth` (metres, row-major `w` x `h`, 0 = no hit) in place.
///
/// In order: pixels the second imager (at +baseline along x) cannot see are 0 (the stereo
/// shadow, derived from the clean depth, including the band on the left where the point
/// falls outside the second image); discontinuity pixels become holes with probability
/// `edge_dropout`, any other with `dropout`; the rest get Gaussian noise of
/// σ_z = z² σ_d / (f b); the result is rounded to `depth_unit_m` and set to 0 outside
/// `range_m`.
pub fn apply_d455(
    spec: &D455Spec,
    fx: f64,
    w: usize,
    h: usize,
    depth: &mut [f32],
    rng: &mut ChaCha8Rng,
) {
    let fb = fx * spec.baseline_m;
    let shadow = if spec.stereo_shadow {
        viewpoint_shadow(depth, w, h, fb, true)
    } else {
        vec![false; w * h]
    };
    let edges = discontinuities(depth, w, h, spec.edge_jump_rel as f32);
    let k = spec.subpixel_sigma_px / fb;
    let [lo, hi] = spec.range_m;
    let mut normal = Normal::new();
    for (i, d) in depth.iter_mut().enumerate() {
        let z = f64::from(*d);
        if z <= 0.0 {
            continue;
        }
        // The draws happen for every hit pixel whatever the outcome, so one pixel's fate
        // does not shift the noise of the others.
        let hole_draw: f64 = rng.gen();
        let n = normal.sample(rng);
        let p_hole = if edges[i] {
            spec.edge_dropout
        } else {
            spec.dropout
        };
        if shadow[i] || hole_draw < p_hole {
            *d = 0.0;
            continue;
        }
        let zn = quantize(z + z * z * k * n, spec.depth_unit_m);
        *d = if zn >= lo && zn <= hi { zn as f32 } else { 0.0 };
    }
}
