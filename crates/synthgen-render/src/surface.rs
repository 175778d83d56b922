//! Image textures tiled over the ground and the walls: decoded images turned once (per
//! renderer) into linear-light mip chains with power-of-two sides, sampled per pixel at the
//! mip level that matches the pixel's footprint on the plane (nearest texel), so far and
//! grazing parts of a plane average the texture instead of aliasing.

use std::sync::Arc;

use synthgen_core::sample::SurfaceTexture;
use synthgen_core::Texture;

use crate::bits::floor_low_bits;
use crate::color::srgb_to_linear_f32;
use crate::prepare::validate_texture;
use crate::Error;

/// Largest side of a prepared texture; larger images are averaged down to it.
const MAX_SIDE_LOG2: u32 = 10;

/// A texture ready for tiling: linear RGB, sides 2^w_log2 x 2^h_log2, with its mip chain.
#[derive(Debug)]
pub(crate) struct SurfaceImage {
    w_log2: u32,
    h_log2: u32,
    /// Source height / width: a tile keeps the image's aspect ratio.
    aspect: f32,
    /// Level 0, then each level halved (2x2 box averages), concatenated.
    texels: Vec<[f32; 3]>,
    /// Start of each level in `texels`.
    level_start: Vec<u32>,
}

/// The power of two nearest to `n` in log scale, within 1..=2^MAX_SIDE_LOG2.
fn pow2_log2(n: u32) -> u32 {
    let l = (n.max(1) as f64).log2().round() as u32;
    l.min(MAX_SIDE_LOG2)
}

/// Halves a linear image along x (pairs averaged; an odd last column is dropped).
fn halve_x(img: &[[f32; 3]], w: usize, h: usize) -> (Vec<[f32; 3]>, usize) {
    let nw = (w / 2).max(1);
    let mut out = Vec::with_capacity(nw * h);
    for y in 0..h {
        for x in 0..nw {
            let a = img[y * w + (2 * x).min(w - 1)];
            let b = img[y * w + (2 * x + 1).min(w - 1)];
            out.push(std::array::from_fn(|c| 0.5 * (a[c] + b[c])));
        }
    }
    (out, nw)
}

/// Halves a linear image along y.
fn halve_y(img: &[[f32; 3]], w: usize, h: usize) -> (Vec<[f32; 3]>, usize) {
    let nh = (h / 2).max(1);
    let mut out = Vec::with_capacity(w * nh);
    for y in 0..nh {
        for x in 0..w {
            let a = img[(2 * y).min(h - 1) * w + x];
            let b = img[(2 * y + 1).min(h - 1) * w + x];
            out.push(std::array::from_fn(|c| 0.5 * (a[c] + b[c])));
        }
    }
    (out, nh)
}

/// Bilinear resample (wrapping, as the texture tiles) of a w x h image to nw x nh.
fn resample(img: &[[f32; 3]], w: usize, h: usize, nw: usize, nh: usize) -> Vec<[f32; 3]> {
    if (w, h) == (nw, nh) {
        return img.to_vec();
    }
    // Output index i of n_out samples source positions i0 and i1 (wrapped) of n_src, weight f
    // on i1.
    let taps = |i: usize, n_src: usize, n_out: usize| {
        let s = (i as f64 + 0.5) * n_src as f64 / n_out as f64 - 0.5;
        let i0 = s.floor();
        let f = (s - i0) as f32;
        let i0 = (i0 as i64).rem_euclid(n_src as i64) as usize;
        (i0, (i0 + 1) % n_src, f)
    };
    let mut out = Vec::with_capacity(nw * nh);
    for y in 0..nh {
        let (y0, y1, fy) = taps(y, h, nh);
        for x in 0..nw {
            let (x0, x1, fx) = taps(x, w, nw);
            let p = |xx: usize, yy: usize| img[yy * w + xx];
            let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
            out.push(std::array::from_fn(|k| {
                let top = a[k] + fx * (b[k] - a[k]);
                let bot = c[k] + fx * (d[k] - c[k]);
                top + fy * (bot - top)
            }));
        }
    }
    out
}

impl SurfaceImage {
    /// Validates `tex`, converts it to linear light, brings it to power-of-two sides (box
    /// halvings, then bilinear) and builds the mip chain down to a side of 1.
    pub fn new(tex: &Texture) -> Result<SurfaceImage, Error> {
        validate_texture(tex)?;
        let (mut w, mut h) = (tex.width as usize, tex.height as usize);
        let mut img: Vec<[f32; 3]> = tex
            .rgb
            .chunks_exact(3)
            .map(|p| std::array::from_fn(|c| srgb_to_linear_f32(p[c] as f32 / 255.0)))
            .collect();
        let (w_log2, h_log2) = (pow2_log2(tex.width), pow2_log2(tex.height));
        let (nw, nh) = (1usize << w_log2, 1usize << h_log2);
        while w >= 2 * nw {
            (img, w) = halve_x(&img, w, h);
        }
        while h >= 2 * nh {
            (img, h) = halve_y(&img, w, h);
        }
        let mut level = resample(&img, w, h, nw, nh);
        let (mut lw, mut lh) = (nw, nh);
        let levels = w_log2.min(h_log2);
        let mut texels = Vec::with_capacity(nw * nh * 4 / 3 + 1);
        let mut level_start = Vec::with_capacity(levels as usize + 1);
        for _ in 0..=levels {
            level_start.push(texels.len() as u32);
            texels.extend_from_slice(&level);
            if lw > 1 && lh > 1 {
                let (hx, nw2) = halve_x(&level, lw, lh);
                let (hy, nh2) = halve_y(&hx, nw2, lh);
                (level, lw, lh) = (hy, nw2, nh2);
            }
        }
        Ok(SurfaceImage {
            w_log2,
            h_log2,
            aspect: tex.height as f32 / tex.width as f32,
            texels,
            level_start,
        })
    }

    /// Prepares every image of a folder's list.
    pub fn prepare_all(images: &[Arc<Texture>]) -> Result<Vec<Arc<SurfaceImage>>, Error> {
        images
            .iter()
            .map(|t| SurfaceImage::new(t).map(Arc::new))
            .collect()
    }
}

/// One frame's mapping of a plane's (u, v), metres, onto a `SurfaceImage`.
#[derive(Clone, Copy)]
pub(crate) struct TexMap<'a> {
    img: &'a SurfaceImage,
    /// Level-0 texels per metre along u and v.
    tpm: [f32; 2],
    /// Offset in level-0 texels.
    off: [f32; 2],
    /// Texels per metre of footprint used to choose the level (the larger of `tpm`),
    /// times sqrt 2 so the level's texel is at most about the footprint.
    lod_scale: f32,
    max_level: i32,
    w_mask: i32,
    h_mask: i32,
}

impl<'a> TexMap<'a> {
    /// The mapping of `t` onto the image it picks from `images` (None when there are none).
    pub fn new(t: &SurfaceTexture, images: &'a [Arc<SurfaceImage>]) -> Option<TexMap<'a>> {
        if images.is_empty() {
            return None;
        }
        let img = &*images[(t.image % images.len() as u64) as usize];
        let (w, h) = ((1u32 << img.w_log2) as f32, (1u32 << img.h_log2) as f32);
        let scale = t.scale_m as f32;
        let tpm = [w / scale, h / (scale * img.aspect)];
        Some(TexMap {
            img,
            tpm,
            off: [t.offset[0] as f32 * w, t.offset[1] as f32 * h],
            lod_scale: tpm[0].max(tpm[1]) * std::f32::consts::SQRT_2,
            max_level: img.w_log2.min(img.h_log2) as i32,
            w_mask: (1i32 << img.w_log2) - 1,
            h_mask: (1i32 << img.h_log2) - 1,
        })
    }

    /// The linear texel at plane coordinates (u, v) for a pixel whose footprint on the
    /// plane is `footprint_m` wide: the mip level whose texel is the footprint (rounded in
    /// log2), nearest texel, tiled.
    #[inline(always)]
    pub fn fetch(&self, u: f32, v: f32, footprint_m: f32) -> [f32; 3] {
        let r = footprint_m * self.lod_scale;
        // floor(log2(r)) from the exponent bits; NaN and inf give the coarsest level.
        let level = (((r.to_bits() >> 23) & 0xff) as i32 - 127).clamp(0, self.max_level);
        let iu = (floor_low_bits(u * self.tpm[0] + self.off[0]) & self.w_mask) >> level;
        let iv = (floor_low_bits(v * self.tpm[1] + self.off[1]) & self.h_mask) >> level;
        let row = (self.img.w_log2 as i32 - level) as u32;
        let i =
            self.img.level_start[level as usize] as usize + ((iv as usize) << row) + iu as usize;
        // i < texels.len() by construction (iu, iv within the level's sides).
        self.img.texels.get(i).copied().unwrap_or([0.0; 3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn tex(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) -> Texture {
        let mut rgb = Vec::new();
        for y in 0..h {
            for x in 0..w {
                rgb.extend_from_slice(&f(x, y));
            }
        }
        Texture {
            width: w,
            height: h,
            rgb,
            source: PathBuf::from("t.png"),
        }
    }

    #[test]
    fn mip_chain_averages_and_keeps_power_of_two_sides() {
        let img = SurfaceImage::new(&tex(
            8,
            4,
            |x, y| {
                if (x + y) % 2 == 0 {
                    [255; 3]
                } else {
                    [0; 3]
                }
            },
        ))
        .unwrap();
        assert_eq!((img.w_log2, img.h_log2), (3, 2));
        assert_eq!(img.level_start, vec![0, 32, 40]);
        // A checker averages to 0.5 linear from level 1 on.
        for t in &img.texels[32..] {
            assert!((t[0] - 0.5).abs() < 1e-6, "{t:?}");
        }
        // Odd sizes become powers of two.
        let odd = SurfaceImage::new(&tex(300, 190, |_, _| [128; 3])).unwrap();
        assert_eq!((odd.w_log2, odd.h_log2), (8, 8));
        assert!(odd
            .texels
            .iter()
            .all(|t| (t[1] - odd.texels[0][1]).abs() < 1e-5));
        let bad = Texture {
            rgb: vec![0; 5],
            ..tex(2, 2, |_, _| [0; 3])
        };
        assert!(SurfaceImage::new(&bad).is_err());
    }

    #[test]
    fn fetch_tiles_and_picks_coarser_levels_for_larger_footprints() {
        let img = Arc::new(
            SurfaceImage::new(&tex(4, 4, |x, _| if x < 2 { [255; 3] } else { [0; 3] })).unwrap(),
        );
        let images = vec![img];
        let t = SurfaceTexture {
            image: 5,
            offset: [0.0, 0.0],
            scale_m: 1.0,
        };
        let m = TexMap::new(&t, &images).unwrap();
        // Fine footprint: level 0, left half white, right half black, repeating every metre.
        assert_eq!(m.fetch(0.1, 0.3, 0.01)[0], 1.0);
        assert_eq!(m.fetch(0.6, 0.3, 0.01)[0], 0.0);
        assert_eq!(m.fetch(2.1, -3.7, 0.01)[0], 1.0);
        assert_eq!(m.fetch(-0.4, 0.0, 0.01)[0], 0.0);
        // A footprint of the whole tile: the 1x1 level, the mean.
        assert!((m.fetch(0.1, 0.3, 1.0)[0] - 0.5).abs() < 1e-6);
        assert!((m.fetch(0.1, 0.3, f32::INFINITY)[0] - 0.5).abs() < 1e-6);
        assert!(TexMap::new(&t, &[]).is_none());
    }
}
