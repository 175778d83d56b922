//! The procedural textures shipped in the repo's `textures/` folder (256 x 256, tileable),
//! generated deterministically from integer hashes so that they can be re-made bit for bit:
//! `cargo run -p synthgen-render --example make_textures -- textures`. A test checks that
//! the committed PNGs equal this output.

use std::path::PathBuf;

use synthgen_core::Texture;

use crate::ground::hash32;

/// Side of every generated texture, pixels.
pub const SIDE: u32 = 256;

/// (folder, name) of every texture, as laid out under `textures/`.
pub const TEXTURES: [(&str, &str); 6] = [
    ("ground", "wood"),
    ("ground", "tiles"),
    ("ground", "marble"),
    ("ground", "concrete"),
    ("walls", "plaster"),
    ("walls", "fabric"),
];

/// Periodic value noise in 0..1: a lattice of `cells` x `cells` random values over the
/// texture (so it tiles), smoothstep-interpolated; `x`, `y` in pixels.
fn value_noise(x: f32, y: f32, cells: u32, seed: u32) -> f32 {
    let s = SIDE as f32 / cells as f32;
    let (gx, gy) = (x / s, y / s);
    let (ix, iy) = (gx.floor(), gy.floor());
    let (fx, fy) = (gx - ix, gy - iy);
    let (ix, iy) = (ix as i64, iy as i64);
    let c = cells as i64;
    let v = |i: i64, j: i64| {
        let (i, j) = (i.rem_euclid(c) as u32, j.rem_euclid(c) as u32);
        (hash32(i ^ (j << 12) ^ seed.wrapping_mul(0x9e37_79b9)) >> 8) as f32 / 16_777_216.0
    };
    let sm = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (sm(fx), sm(fy));
    let top = v(ix, iy) + sx * (v(ix + 1, iy) - v(ix, iy));
    let bot = v(ix, iy + 1) + sx * (v(ix + 1, iy + 1) - v(ix, iy + 1));
    top + sy * (bot - top)
}

/// Fractal sum of `octaves` noises from `cells` cells up, each twice as fine and half as
/// strong, normalized to 0..1.
fn fbm(x: f32, y: f32, cells: u32, octaves: u32, seed: u32) -> f32 {
    let (mut sum, mut amp, mut norm) = (0.0, 1.0, 0.0);
    for o in 0..octaves {
        sum += amp * value_noise(x, y, cells << o, seed.wrapping_add(o * 7919));
        norm += amp;
        amp *= 0.5;
    }
    sum / norm
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    std::array::from_fn(|c| a[c] + (b[c] - a[c]) * t.clamp(0.0, 1.0))
}

/// A pixel's colour (sRGB 0..1) of texture `name`, None for an unknown name.
fn pixel(name: &str, x: f32, y: f32) -> Option<[f32; 3]> {
    let tau = std::f32::consts::TAU;
    Some(match name {
        // Planks along x with growth rings bent by noise and fine grain along the fibres.
        "wood" => {
            let plank = (y / 64.0).floor();
            let warp = fbm(x, y, 4, 3, 11 + plank as u32);
            let rings = (((y / 64.0).fract() * 3.0 + warp * 2.5) * tau).sin() * 0.5 + 0.5;
            let grain = value_noise(x * 0.25, y * 4.0, 32, 17);
            let gap = if (y as u32) % 64 < 2 { 0.55 } else { 1.0 };
            let tone = 0.92 + 0.16 * value_noise(0.0, plank * 64.0 + 32.0, 4, 23);
            let c = mix(
                [0.62, 0.42, 0.24],
                [0.42, 0.26, 0.13],
                rings * 0.7 + grain * 0.3,
            );
            c.map(|v| v * gap * tone)
        }
        // 4 x 4 ceramic tiles with grout lines, each tile its own shade, a little mottling.
        "tiles" => {
            let (tx, ty) = ((x / 64.0).floor() as u32, (y / 64.0).floor() as u32);
            let (lx, ly) = (x % 64.0, y % 64.0);
            let grout = lx < 3.0 || ly < 3.0;
            let shade = (hash32(tx | (ty << 8) ^ 0x7e11) >> 24) as f32 / 255.0;
            let mottle = fbm(x, y, 16, 2, 31);
            if grout {
                let g = 0.45 + 0.1 * mottle;
                [g, g * 0.97, g * 0.93]
            } else {
                let base = mix([0.78, 0.8, 0.82], [0.55, 0.62, 0.68], shade);
                base.map(|v| v * (0.94 + 0.08 * mottle))
            }
        }
        // White marble with dark veins from a noise-warped sine.
        "marble" => {
            let turb = fbm(x, y, 4, 4, 41);
            let v = ((x / SIDE as f32 + turb * 1.5) * tau).sin();
            let vein = (1.0 - v.abs()).powi(12);
            let base = mix([0.93, 0.92, 0.9], [0.84, 0.84, 0.83], fbm(x, y, 8, 2, 43));
            mix(base, [0.35, 0.36, 0.4], vein)
        }
        // Grey concrete: broad blotches, finer grain, a few dark pores.
        "concrete" => {
            let n = 0.6 * fbm(x, y, 4, 3, 51) + 0.4 * value_noise(x, y, 64, 53);
            let pore = if hash32((x as u32) | ((y as u32) << 9) ^ 0xc0c0).is_multiple_of(97) {
                0.7
            } else {
                1.0
            };
            let g = (0.42 + 0.25 * n) * pore;
            [g, g * 0.99, g * 0.96]
        }
        // Painted plaster: a soft warm white with gentle large-scale variation.
        "plaster" => {
            let n = fbm(x, y, 4, 3, 61);
            mix([0.86, 0.83, 0.76], [0.74, 0.71, 0.66], n)
        }
        // Woven fabric: alternating over/under threads, blue-grey with thread noise.
        "fabric" => {
            let (cx, cy) = ((x / 4.0).floor() as u32, (y / 4.0).floor() as u32);
            let over = (cx + cy) % 2 == 0;
            let across = if over { y % 4.0 } else { x % 4.0 };
            let thread = (std::f32::consts::PI * (across + 0.5) / 4.0).sin();
            let n = value_noise(x, y, 32, 71);
            let base = if over {
                [0.25, 0.33, 0.48]
            } else {
                [0.32, 0.4, 0.55]
            };
            base.map(|v| v * (0.7 + 0.3 * thread) * (0.95 + 0.1 * n))
        }
        _ => return None,
    })
}

/// The texture `name` (one of `TEXTURES`), or None for an unknown name. `source` is set to
/// `<folder>/<name>.png`.
pub fn texture(name: &str) -> Option<Texture> {
    let folder = TEXTURES.iter().find(|(_, n)| *n == name)?.0;
    let mut rgb = Vec::with_capacity((SIDE * SIDE * 3) as usize);
    for y in 0..SIDE {
        for x in 0..SIDE {
            let c = pixel(name, x as f32 + 0.5, y as f32 + 0.5)?;
            rgb.extend(c.map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8));
        }
    }
    Some(Texture {
        width: SIDE,
        height: SIDE,
        rgb,
        source: PathBuf::from(format!("{folder}/{name}.png")),
    })
}
