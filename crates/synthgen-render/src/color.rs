//! sRGB <-> linear conversions. Shading happens in linear light; the tables make both
//! directions a lookup.

/// Entries of the linear -> sRGB table. 8192 steps keep the error at most one 8-bit level
/// even in the darks, where the sRGB curve is steepest (slope 12.92).
const TO_SRGB_STEPS: usize = 8192;
/// The largest index of the linear -> sRGB table: `srgb_index` takes values in 0..=this.
pub(crate) const TO_SRGB_MAX: usize = TO_SRGB_STEPS - 1;

pub(crate) fn srgb_to_linear_f32(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb_f32(l: f32) -> f32 {
    let l = l.clamp(0.0, 1.0);
    if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Index into the sRGB table for a value pre-scaled by `TO_SRGB_MAX`: clamped, rounded, and
/// computed with float bit tricks instead of a (scalar, saturating) float-to-int cast so the
/// loop vectorizes.
#[inline(always)]
pub(crate) fn srgb_index(v: f32) -> u16 {
    srgb_index32(v) as u16
}

/// `srgb_index` kept in 32 bits, which saves packing lanes to 16 bits in vector code.
#[inline(always)]
pub(crate) fn srgb_index32(v: f32) -> u32 {
    let v = v.max(0.0).min(TO_SRGB_MAX as f32); // NaN -> 0
    (v + MAGIC).to_bits() & 0xffff
}

/// 1.5 * 2^23: adding it to |x| < 2^22 leaves round(x) in the low mantissa bits.
pub(crate) const MAGIC: f32 = 12_582_912.0;

/// Both conversion tables, built once per renderer.
#[derive(Clone)]
pub(crate) struct ColorLuts {
    /// sRGB byte -> linear 0..1.
    pub to_linear: [f32; 256],
    /// Indexed by any u16, so lookups need no bounds check or mask; entries past
    /// `TO_SRGB_MAX` repeat the last one (they are never touched, so never cached).
    to_srgb: Box<[u8; 1 << 16]>,
}

impl ColorLuts {
    pub fn new() -> ColorLuts {
        let to_linear = std::array::from_fn(|i| srgb_to_linear_f32(i as f32 / 255.0));
        let to_srgb = Box::new(std::array::from_fn(|i| {
            let l = i.min(TO_SRGB_MAX) as f32 / (TO_SRGB_STEPS - 1) as f32;
            (linear_to_srgb_f32(l) * 255.0 + 0.5) as u8
        }));
        ColorLuts { to_linear, to_srgb }
    }

    /// The table entry `i` (`0..=TO_SRGB_MAX`, as `srgb_index` gives; larger indices give
    /// the entry at `TO_SRGB_MAX`).
    #[inline(always)]
    pub fn srgb_at(&self, i: u16) -> u8 {
        // A u16 index is always in range: no bounds check in the hot loops.
        self.to_srgb[i as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn to_srgb(l: &ColorLuts, v: f32) -> u8 {
        l.srgb_at(srgb_index(v * TO_SRGB_MAX as f32))
    }

    #[test]
    fn round_trip_every_byte() {
        let l = ColorLuts::new();
        for b in 0..=255u8 {
            assert_eq!(to_srgb(&l, l.to_linear[b as usize]), b);
        }
        assert_eq!(to_srgb(&l, -1.0), 0);
        assert_eq!(to_srgb(&l, 7.0), 255);
        assert_eq!(to_srgb(&l, f32::NAN), 0);
    }

    #[test]
    fn table_index_rounds_and_clamps() {
        assert_eq!(srgb_index(0.49), 0);
        assert_eq!(srgb_index(0.51), 1);
        assert_eq!(srgb_index(1234.4), 1234);
        assert_eq!(srgb_index(1e9), TO_SRGB_MAX as u16);
        assert_eq!(srgb_index(-5.0), 0);
        assert_eq!(srgb_index(f32::INFINITY), TO_SRGB_MAX as u16);
    }
}
