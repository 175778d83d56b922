//! Cycles' render passes → the parts of a `RenderedFrame`: sRGB bytes composited over the
//! sampled background, depth along the optical axis, instance ids.
//!
//! Cycles' Z pass (`use_pass_z`) is the distance along the camera's view axis (Cycles'
//! `camera_z_depth`), which is already the OpenCV depth (z in the camera frame); the y scale
//! for `fy != fx` (see [`crate::camera`]) does not change it. Where a camera ray hits nothing,
//! Cycles writes 1e10. The Object Index pass holds `pass_index`, which the scene script sets
//! to `i + 1` for object i (0 for the ground).

/// Z values at or beyond this are "no hit" (Cycles writes 1e10 there).
pub const NO_HIT_Z_M: f32 = 1.0e9;

/// Depth in metres along the optical axis from the Z pass; 0 where nothing was hit.
pub fn depth_from_z(z: &[f32]) -> Vec<f32> {
    z.iter()
        .map(|&v| {
            if v.is_finite() && v > 0.0 && v < NO_HIT_Z_M {
                v
            } else {
                0.0
            }
        })
        .collect()
}

/// Instance ids from the Object Index pass: `round(index)`, 0 for anything not in
/// `1..=objects`.
pub fn instance_from_index(index: &[f32], objects: usize) -> Vec<u16> {
    index
        .iter()
        .map(|&v| {
            let r = v.round();
            if r >= 1.0 && r <= objects as f32 {
                r as u16
            } else {
                0
            }
        })
        .collect()
}

pub fn srgb_to_linear(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

pub fn linear_to_srgb(l: f32) -> f32 {
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Cycles' Combined pass (linear, alpha premultiplied, transparent film) over an sRGB
/// background, to 8-bit sRGB ("Standard" view transform: clamp, then the sRGB curve).
pub fn composite_over(rgba_linear: &[f32], background_srgb: &[u8]) -> Vec<u8> {
    let lut: Vec<f32> = (0..=255u8)
        .map(|b| srgb_to_linear(f32::from(b) / 255.0))
        .collect();
    rgba_linear
        .chunks_exact(4)
        .zip(background_srgb.chunks_exact(3))
        .flat_map(|(c, bg)| {
            let a = if c[3].is_finite() {
                c[3].clamp(0.0, 1.0)
            } else {
                1.0
            };
            std::array::from_fn::<u8, 3, _>(|i| {
                let l = c[i] + (1.0 - a) * lut[usize::from(bg[i])];
                (linear_to_srgb(l) * 255.0 + 0.5) as u8
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_drops_misses() {
        assert_eq!(
            depth_from_z(&[0.5, 1.0e10, f32::INFINITY, f32::NAN, -1.0, 2.25]),
            vec![0.5, 0.0, 0.0, 0.0, 0.0, 2.25]
        );
    }

    #[test]
    fn index_rounds_and_clamps() {
        assert_eq!(
            instance_from_index(&[0.0, 1.0, 2.0001, 2.9999, 4.0, -1.0], 3),
            vec![0, 1, 2, 3, 0, 0]
        );
    }

    #[test]
    fn transparent_shows_background_opaque_hides_it() {
        let rgba = [
            0.0, 0.0, 0.0, 0.0, 1.0, 0.2158, 0.0, 1.0, 0.1, 0.1, 0.1, 0.5,
        ];
        let bg = [200, 100, 50, 10, 20, 30, 255, 255, 255];
        let out = composite_over(&rgba, &bg);
        assert_eq!(&out[..3], &[200, 100, 50]);
        assert_eq!(&out[3..6], &[255, 128, 0]); // 0.2158 linear is sRGB 0.5
                                                // Half coverage of dark grey over white: 0.1 + 0.5 * 1.0 linear.
        let want = (linear_to_srgb(0.6) * 255.0 + 0.5) as u8;
        assert_eq!(&out[6..], &[want; 3]);
    }

    #[test]
    fn srgb_round_trip() {
        for b in 0..=255u8 {
            let v = f32::from(b) / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5);
        }
    }
}
