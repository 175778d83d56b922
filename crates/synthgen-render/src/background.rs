//! What is seen where no geometry is: a plain colour, per-pixel noise, or a random crop of a
//! background image, all determined by the frame's background seed.

use std::sync::Arc;

use synthgen_core::rng::splitmix64;
use synthgen_core::sample::BackgroundSample;
use synthgen_core::scene::BackgroundKind;
use synthgen_core::Texture;

use crate::ground::hash32;
use crate::Error;

/// Smallest crop, as a fraction of the largest crop with the image's aspect ratio.
const MIN_CROP: f64 = 0.5;

pub(crate) enum Background<'a> {
    Color([u8; 3]),
    Noise {
        key: u32,
    },
    /// Nearest-neighbour lookup through per-column and per-row maps into the texture.
    Image {
        tex: &'a Texture,
        xmap: &'a [u32],
        ymap: &'a [u32],
    },
}

/// A uniform value in [0, 1) from a 64-bit hash.
fn unit(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

impl<'a> Background<'a> {
    /// Sets up the frame's background; `xmap`/`ymap` are scratch for the image crop.
    pub fn new(
        b: &BackgroundSample,
        images: &'a [Arc<Texture>],
        width: usize,
        height: usize,
        xmap: &'a mut Vec<u32>,
        ymap: &'a mut Vec<u32>,
    ) -> Result<Background<'a>, Error> {
        Ok(match b.kind {
            BackgroundKind::Color => {
                Background::Color(b.color.map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
            }
            BackgroundKind::Noise => Background::Noise {
                key: (splitmix64(b.seed) >> 32) as u32,
            },
            BackgroundKind::Images => {
                if images.is_empty() {
                    return Err(Error::NoBackgroundImages);
                }
                let h0 = splitmix64(b.seed);
                let tex = &*images[(h0 % images.len() as u64) as usize];
                let (tw, th) = (tex.width as f64, tex.height as f64);
                // Largest crop with the output's aspect ratio, then a random scale and offset.
                let aspect = width as f64 / height as f64;
                let (cw0, ch0) = if tw / th > aspect {
                    (th * aspect, th)
                } else {
                    (tw, tw / aspect)
                };
                let s = MIN_CROP + (1.0 - MIN_CROP) * unit(splitmix64(h0 ^ 1));
                let (cw, ch) = (cw0 * s, ch0 * s);
                let ox = (tw - cw) * unit(splitmix64(h0 ^ 2));
                let oy = (th - ch) * unit(splitmix64(h0 ^ 3));
                let flip = splitmix64(h0 ^ 4) & 1 == 1;
                xmap.clear();
                xmap.extend((0..width).map(|x| {
                    let x = if flip { width - 1 - x } else { x };
                    let tx = ox + (x as f64 + 0.5) * cw / width as f64;
                    (tx as u32).min(tex.width - 1)
                }));
                ymap.clear();
                ymap.extend((0..height).map(|y| {
                    let ty = oy + (y as f64 + 0.5) * ch / height as f64;
                    (ty as u32).min(tex.height - 1)
                }));
                Background::Image {
                    tex,
                    xmap: &xmap[..],
                    ymap: &ymap[..],
                }
            }
        })
    }

    /// Fills the pixels of row `y` whose depth is 0.
    pub fn fill_row(&self, y: usize, depth: &[f32], rgb: &mut [u8]) {
        // Most rows of a typical frame are all ground and objects: a quick vectorized check
        // skips them.
        if !depth.iter().fold(false, |any, &d| any | (d == 0.0)) {
            return;
        }
        let width = depth.len();
        match self {
            Background::Color(c) => {
                for (d, px) in depth.iter().zip(rgb.chunks_exact_mut(3)) {
                    if *d == 0.0 {
                        px.copy_from_slice(c);
                    }
                }
            }
            Background::Noise { key } => {
                let base = (y * width) as u32;
                for (x, (d, px)) in depth.iter().zip(rgb.chunks_exact_mut(3)).enumerate() {
                    if *d == 0.0 {
                        let h = hash32((base + x as u32) ^ key).to_le_bytes();
                        px.copy_from_slice(&h[..3]);
                    }
                }
            }
            Background::Image { tex, xmap, ymap } => {
                let row = ymap[y] as usize * tex.width as usize;
                for ((d, px), &tx) in depth.iter().zip(rgb.chunks_exact_mut(3)).zip(xmap.iter()) {
                    if *d == 0.0 {
                        let i = (row + tx as usize) * 3;
                        px.copy_from_slice(&tex.rgb[i..i + 3]);
                    }
                }
            }
        }
    }
}
