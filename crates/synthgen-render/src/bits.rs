//! Branch-free float helpers shared by the vectorized row loops (ground, raster, surface
//! textures): a select and a floor without a float-to-int cast, so the loops stay SIMD.

use crate::color::MAGIC;

/// `if c { a } else { b }` as bit operations. A plain `if` on a value loaded from the
/// same slot gets turned into a conditional store, which does not vectorize.
#[inline(always)]
pub(crate) fn select(c: bool, a: f32, b: f32) -> f32 {
    let m = 0u32.wrapping_sub(c as u32);
    f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// floor(x) modulo 2^16 (enough for the tile masks), for |x| < 2^21, without a float-to-int
/// cast.
#[inline(always)]
pub(crate) fn floor_low_bits(x: f32) -> i32 {
    ((x - 0.5 + MAGIC).to_bits() & 0xffff) as i32
}
