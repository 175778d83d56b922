//! Colour maths for scene sampling: black-body light colours, sRGB decoding, hue rotation.

/// sRGB (0..1) to linear light (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The colour of a black body at `kelvin`, in linear RGB scaled so that its largest channel
/// is 1 (intensity stays a separate knob).
///
/// Tanner Helland's fit (2012) to Mitchell Charity's black-body sRGB table, with t = K / 100:
/// R = 255 for t ≤ 66, else 329.699 (t − 60)^−0.13320;
/// G = 99.4708 ln t − 161.120 for t ≤ 66, else 288.122 (t − 60)^−0.075515;
/// B = 255 for t ≥ 66, 0 for t ≤ 19, else 138.518 ln(t − 10) − 305.045;
/// each clamped to 0..255, read as sRGB and decoded to linear. Valid for 1000–40000 K.
pub fn kelvin_to_rgb(kelvin: f64) -> [f32; 3] {
    let t = kelvin.clamp(1000.0, 40_000.0) / 100.0;
    let r = if t <= 66.0 {
        255.0
    } else {
        329.698_727_446 * (t - 60.0).powf(-0.133_204_759_2)
    };
    let g = if t <= 66.0 {
        99.470_802_586_1 * t.ln() - 161.119_568_166_1
    } else {
        288.122_169_528_3 * (t - 60.0).powf(-0.075_514_849_2)
    };
    let b = if t >= 66.0 {
        255.0
    } else if t <= 19.0 {
        0.0
    } else {
        138.517_731_223_1 * (t - 10.0).ln() - 305.044_792_730_7
    };
    let lin = [r, g, b].map(|v| srgb_to_linear((v.clamp(0.0, 255.0) / 255.0) as f32));
    let m = lin.iter().copied().fold(f32::MIN, f32::max).max(1e-6);
    lin.map(|v| v / m)
}

/// The 3x3 matrix (row-major) that rotates linear RGB colours by `deg` about the grey axis
/// (1, 1, 1) / √3 (Rodrigues): greys stay grey, saturated colours change hue.
pub fn hue_rotation(deg: f64) -> [[f32; 3]; 3] {
    let (s, c) = deg.to_radians().sin_cos();
    let k = (1.0 - c) / 3.0;
    let q = s / 3f64.sqrt();
    let m = [
        [c + k, k - q, k + q],
        [k + q, c + k, k - q],
        [k - q, k + q, c + k],
    ];
    m.map(|r| r.map(|v| v as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn black_body_colours_go_from_red_to_blue() {
        let warm = kelvin_to_rgb(2700.0);
        let d65 = kelvin_to_rgb(6600.0);
        let cold = kelvin_to_rgb(10_000.0);
        assert_eq!(warm[0], 1.0);
        assert!(warm[2] < 0.35 * warm[0], "{warm:?}");
        assert!(d65.iter().all(|&v| v > 0.9), "{d65:?}");
        assert_eq!(cold[2], 1.0);
        assert!(cold[0] < 0.8, "{cold:?}");
    }

    #[test]
    fn hue_rotation_keeps_grey_and_cycles_primaries() {
        let m = hue_rotation(120.0);
        let apply = |v: [f32; 3]| -> [f32; 3] {
            std::array::from_fn(|i| (0..3).map(|j| m[i][j] * v[j]).sum())
        };
        let g = apply([0.5; 3]);
        assert!(g.iter().all(|v| (v - 0.5).abs() < 1e-6), "{g:?}");
        let r = apply([1.0, 0.0, 0.0]);
        assert!((r[1] - 1.0).abs() < 1e-6 && r[0].abs() < 1e-6, "{r:?}");
    }
}
