//! The RGB model's input: the colour around each instance's box, kept at load time, and the
//! crops cut from it per batch — the nominal box for evaluation, a jittered box (and jittered
//! colours) for training, so that the model does not rely on a perfect detector.
//!
//! Boxes are square (the longer side of `bbox_visib` times [`CONTEXT`], centred on it), so a
//! crop shows the object undistorted and its side in pixels says how far the object is.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use synthgen_core::rng::splitmix64;

use crate::data::{crop_resize, Instance};
use crate::models::rgb::{Pinhole, SquareBox};

/// The nominal crop's side over the box's longer side (some context around the object).
pub const CONTEXT: f64 = 1.25;
/// The stored region's side over the box's longer side: room for every jittered crop.
pub const STORED_CONTEXT: f64 = 2.0;
/// Training jitter of the box: its centre moves by up to this fraction of its side in x and
/// in y, independently...
pub const JITTER_SHIFT: f64 = 0.15;
/// ...and its side is scaled by a factor in 1 ± this.
pub const JITTER_SCALE: f64 = 0.2;
// The jittered crop stays inside the stored region: CONTEXT · ((1 + JITTER_SCALE) / 2 +
// JITTER_SHIFT) = 0.9375 ≤ STORED_CONTEXT / 2.
const _: () =
    assert!(CONTEXT * ((1.0 + JITTER_SCALE) / 2.0 + JITTER_SHIFT) <= STORED_CONTEXT / 2.0);

/// The colour around one instance's box and where it lies in the image.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxRegion {
    /// `res² × 3` bytes, RGB, row-major: the square `region` resampled.
    pub rgb: Vec<u8>,
    pub res: u32,
    /// The crop the model sees at evaluation.
    pub nominal: SquareBox,
    /// The stored square (same centre, [`STORED_CONTEXT`] / [`CONTEXT`] × the side).
    pub region: SquareBox,
    pub camera: Pinhole,
    /// The dense RGB model's training targets over the same square; `None` when not loaded.
    pub target: Option<CoordRegion>,
}

/// Per-pixel targets of the dense RGB model over a box region: at `res × res` cells of the
/// stored square, the object coordinates (metres, model frame, at the GT pose) of the
/// instance's visible surface, NaN where the instance is not visible.
#[derive(Debug, Clone, PartialEq)]
pub struct CoordRegion {
    pub res: u32,
    pub coords: Vec<[f32; 3]>,
}

impl CoordRegion {
    /// Samples the region's cells from the object coordinates `at(x, y)` of image pixel
    /// (x, y) (NaN where the instance is not visible), nearest pixel; NaN outside the image.
    pub fn sample(
        at: impl Fn(usize, usize) -> [f32; 3],
        width: u32,
        height: u32,
        region: &SquareBox,
        res: u32,
    ) -> CoordRegion {
        let [x0, y0, side, _] = edge_rect(region);
        let step = side / f64::from(res);
        let mut out = Vec::with_capacity((res * res) as usize);
        for j in 0..res {
            let y = (y0 + (f64::from(j) + 0.5) * step).floor();
            for i in 0..res {
                let x = (x0 + (f64::from(i) + 0.5) * step).floor();
                let inside = x >= 0.0 && y >= 0.0 && x < f64::from(width) && y < f64::from(height);
                out.push(if inside {
                    at(x as usize, y as usize)
                } else {
                    [f32::NAN; 3]
                });
            }
        }
        CoordRegion { res, coords: out }
    }

    /// The `size × size` cells of square `b` (image pixels; `region` is the square this was
    /// sampled over), nearest cell; NaN outside.
    pub fn cut(&self, region: &SquareBox, b: &SquareBox, size: u32) -> Vec<[f32; 3]> {
        let per_px = f64::from(self.res) / region.side;
        let [rx, ry, ..] = edge_rect(region);
        let [x0, y0, s, _] = edge_rect(b);
        let step = s / f64::from(size);
        let mut out = Vec::with_capacity((size * size) as usize);
        for j in 0..size {
            let y = ((y0 + (f64::from(j) + 0.5) * step - ry) * per_px).floor();
            for i in 0..size {
                let x = ((x0 + (f64::from(i) + 0.5) * step - rx) * per_px).floor();
                let r = f64::from(self.res);
                out.push(if x >= 0.0 && y >= 0.0 && x < r && y < r {
                    self.coords[y as usize * self.res as usize + x as usize]
                } else {
                    [f32::NAN; 3]
                });
            }
        }
        out
    }
}

/// The nominal square crop of a box `[x, y, w, h]` (BOP's `bbox_visib`: x, y the first pixel,
/// w, h = last − first).
pub fn nominal_box(bbox: [f64; 4]) -> SquareBox {
    SquareBox {
        cx: bbox[0] + 0.5 * bbox[2],
        cy: bbox[1] + 0.5 * bbox[3],
        side: CONTEXT * bbox[2].max(bbox[3]).max(1.0),
    }
}

/// `[x0, y0, side, side]` of a square in the edge coordinates `crop_resize` reads (pixel i
/// spans i..i+1, so the intrinsics' pixel centre u is the edge coordinate u + 0.5).
fn edge_rect(b: &SquareBox) -> [f64; 4] {
    [
        b.cx + 0.5 - 0.5 * b.side,
        b.cy + 0.5 - 0.5 * b.side,
        b.side,
        b.side,
    ]
}

impl BoxRegion {
    /// Cuts the region around `bbox` out of an RGB image, at a resolution that gives a
    /// `crop`-pixel model input about one stored pixel per input pixel.
    pub fn from_image(
        rgb: &[u8],
        width: u32,
        height: u32,
        bbox: [f64; 4],
        crop: u32,
        camera: Pinhole,
    ) -> BoxRegion {
        let nominal = nominal_box(bbox);
        let region = SquareBox {
            side: nominal.side * STORED_CONTEXT / CONTEXT,
            ..nominal
        };
        let res = (f64::from(crop) * STORED_CONTEXT / CONTEXT).ceil() as u32;
        BoxRegion {
            rgb: crop_resize(rgb, width, height, edge_rect(&region), res),
            res,
            nominal,
            region,
            camera,
            target: None,
        }
    }

    /// The `size × size` crop of square `b` (image pixels), resampled from the region.
    pub fn crop(&self, b: &SquareBox, size: u32) -> Vec<u8> {
        let per_px = f64::from(self.res) / self.region.side;
        let [rx, ry, ..] = edge_rect(&self.region);
        let [x0, y0, s, _] = edge_rect(b);
        crop_resize(
            &self.rgb,
            self.res,
            self.res,
            [
                (x0 - rx) * per_px,
                (y0 - ry) * per_px,
                s * per_px,
                s * per_px,
            ],
            size,
        )
    }
}

/// The RNG of one instance at one training step: a pure function of (seed, instance).
fn jitter_rng(seed: u64, inst: &Instance) -> ChaCha8Rng {
    let s = splitmix64(splitmix64(seed ^ u64::from(inst.scene_id)) ^ u64::from(inst.im_id));
    ChaCha8Rng::seed_from_u64(splitmix64(s ^ inst.gt_id as u64))
}

/// A box as an imperfect detector might give it: the centre shifted by up to
/// [`JITTER_SHIFT`] of the side in x and y, the side scaled by 1 ± [`JITTER_SCALE`].
pub fn jittered_box(b: &SquareBox, rng: &mut ChaCha8Rng) -> SquareBox {
    SquareBox {
        cx: b.cx + b.side * rng.gen_range(-JITTER_SHIFT..=JITTER_SHIFT),
        cy: b.cy + b.side * rng.gen_range(-JITTER_SHIFT..=JITTER_SHIFT),
        side: b.side * rng.gen_range(1.0 - JITTER_SCALE..=1.0 + JITTER_SCALE),
    }
}

/// Colour jitter of a training crop: brightness 0.8–1.2, per-channel gain 0.9–1.1 and offset
/// ±10 levels, in place.
fn jitter_colours(crop: &mut [u8], rng: &mut ChaCha8Rng) {
    let brightness = rng.gen_range(0.8..=1.2);
    let gain: [f64; 3] = std::array::from_fn(|_| brightness * rng.gen_range(0.9..=1.1));
    let offset: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-10.0..=10.0));
    for px in crop.chunks_exact_mut(3) {
        for c in 0..3 {
            px[c] = (f64::from(px[c]) * gain[c] + offset[c])
                .round()
                .clamp(0.0, 255.0) as u8;
        }
    }
}

/// Seeds the dense model's augmentation apart from the box and colour jitter.
const DENSE_AUGMENT_STREAM: u64 = 0x6465_6e73_6561_7567;

/// What real photographs bring that the renders lack, for the dense model's training crops
/// (`size` pixels across; `cells`: its `out × out` targets), drawn from (seed, instance):
/// with probability 1/2 a random occluder (a rectangle 20–50 % of the side each way, one
/// random colour with noise) hides the crop and its targets beneath (NaN: not visible); with
/// probability 1/3 a 3×3 blur; then Gaussian-like noise of 0–6 levels (sum of three uniforms).
pub fn dense_augment(
    crop: &mut [u8],
    size: u32,
    cells: &mut [[f32; 3]],
    out: u32,
    seed: u64,
    inst: &Instance,
) {
    let mut rng = jitter_rng(seed ^ DENSE_AUGMENT_STREAM, inst);
    let s = size as usize;
    if rng.gen_bool(0.5) {
        let w = rng.gen_range(0.2..=0.5);
        let h = rng.gen_range(0.2..=0.5);
        let x0 = rng.gen_range(0.0..=1.0 - w);
        let y0 = rng.gen_range(0.0..=1.0 - h);
        let colour: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.0..=255.0));
        let inside = |x: f64, y: f64| x >= x0 && x < x0 + w && y >= y0 && y < y0 + h;
        for (i, px) in crop.chunks_exact_mut(3).enumerate() {
            let (x, y) = (
                ((i % s) as f64 + 0.5) / s as f64,
                ((i / s) as f64 + 0.5) / s as f64,
            );
            if inside(x, y) {
                for c in 0..3 {
                    px[c] = (colour[c] + rng.gen_range(-12.0..=12.0)).clamp(0.0, 255.0) as u8;
                }
            }
        }
        let o = out as usize;
        for (i, c) in cells.iter_mut().enumerate() {
            let (x, y) = (
                ((i % o) as f64 + 0.5) / o as f64,
                ((i / o) as f64 + 0.5) / o as f64,
            );
            if inside(x, y) {
                *c = [f32::NAN; 3];
            }
        }
    }
    if rng.gen_bool(1.0 / 3.0) {
        let src = crop.to_vec();
        for y in 0..s {
            for x in 0..s {
                for c in 0..3 {
                    let mut sum = 0u32;
                    let mut n = 0u32;
                    for yy in y.saturating_sub(1)..=(y + 1).min(s - 1) {
                        for xx in x.saturating_sub(1)..=(x + 1).min(s - 1) {
                            sum += u32::from(src[(yy * s + xx) * 3 + c]);
                            n += 1;
                        }
                    }
                    crop[(y * s + x) * 3 + c] = ((sum + n / 2) / n) as u8;
                }
            }
        }
    }
    let sigma = rng.gen_range(0.0..=6.0);
    if sigma > 0.5 {
        for v in crop.iter_mut() {
            let e: f64 = (0..3).map(|_| rng.gen_range(-1.0..=1.0)).sum::<f64>() * sigma;
            *v = (f64::from(*v) + e).round().clamp(0.0, 255.0) as u8;
        }
    }
}

/// One instance's model input: the crop and the box it was cut from.
pub struct RgbSample {
    pub crop: Vec<u8>,
    pub bbox: SquareBox,
    pub camera: Pinhole,
}

/// The input of one instance: the nominal crop, or with `jitter_seed` (training) a jittered
/// box and colours drawn from (seed, instance). `None` when the instance has no region.
pub fn sample(inst: &Instance, size: u32, jitter_seed: Option<u64>) -> Option<RgbSample> {
    let r = inst.region.as_ref()?;
    let (bbox, crop) = match jitter_seed {
        None => (r.nominal, r.crop(&r.nominal, size)),
        Some(seed) => {
            let mut rng = jitter_rng(seed, inst);
            let b = jittered_box(&r.nominal, &mut rng);
            let mut crop = r.crop(&b, size);
            jitter_colours(&mut crop, &mut rng);
            (b, crop)
        }
    };
    Some(RgbSample {
        crop,
        bbox,
        camera: r.camera,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// An image whose colour encodes the pixel's position: r = x, g = y.
    fn ramp(w: u32, h: u32) -> Vec<u8> {
        (0..h)
            .flat_map(|y| (0..w).flat_map(move |x| [x as u8, y as u8, 99]))
            .collect()
    }

    fn camera() -> Pinhole {
        Pinhole {
            fx: 500.0,
            fy: 500.0,
            cx: 100.0,
            cy: 80.0,
        }
    }

    #[test]
    fn a_crop_of_the_region_equals_the_crop_of_the_image() {
        let (w, h) = (240u32, 200u32);
        let img = ramp(w, h);
        let bbox = [70.0, 60.0, 40.0, 30.0];
        let r = BoxRegion::from_image(&img, w, h, bbox, 32, camera());
        assert_eq!(r.nominal.side, 50.0);
        assert_eq!((r.nominal.cx, r.nominal.cy), (90.0, 75.0));
        assert_eq!(r.region.side, 80.0);
        assert_eq!(r.res, 52);
        // A jittered box, cut from the stored region and straight from the image.
        let b = SquareBox {
            cx: 96.0,
            cy: 70.0,
            side: 58.0,
        };
        let from_region = r.crop(&b, 32);
        let direct = crop_resize(&img, w, h, edge_rect(&b), 32);
        let worst = from_region
            .iter()
            .zip(&direct)
            .map(|(a, b)| (i16::from(*a) - i16::from(*b)).abs())
            .max()
            .unwrap();
        // Two bilinear resamplings of a linear ramp: within a level or two of one.
        assert!(worst <= 2, "worst difference {worst}");
        // The crop's centre pixel shows the box centre (r = x, g = y of the image).
        let c = ((16 * 32 + 16) * 3) as usize;
        assert!((f64::from(from_region[c]) - 96.9).abs() <= 2.0);
        assert!((f64::from(from_region[c + 1]) - 70.9).abs() <= 2.0);
    }

    #[test]
    fn jitter_stays_in_bounds_and_is_seeded() {
        let b = SquareBox {
            cx: 0.0,
            cy: 0.0,
            side: 100.0,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..1000 {
            let j = jittered_box(&b, &mut rng);
            assert!(j.cx.abs() <= 15.0 && j.cy.abs() <= 15.0);
            assert!((80.0..=120.0).contains(&j.side));
            // Inside the stored region (side 160 around the same centre).
            assert!(j.cx.abs() + 0.5 * j.side <= 80.0);
        }
        let inst = Instance {
            scene_id: 1,
            im_id: 2,
            gt_id: 0,
            obj_id: 1,
            points_m: vec![],
            crop_xy: vec![],
            crop_rgb: vec![],
            region: Some(BoxRegion::from_image(
                &ramp(64, 64),
                64,
                64,
                [10.0, 10.0, 20.0, 20.0],
                16,
                camera(),
            )),
            pose: synthgen_core::Pose::IDENTITY,
        };
        let a = sample(&inst, 16, Some(7)).unwrap();
        let again = sample(&inst, 16, Some(7)).unwrap();
        let other = sample(&inst, 16, Some(8)).unwrap();
        assert_eq!((a.bbox, &a.crop), (again.bbox, &again.crop));
        assert_ne!(a.bbox, other.bbox);
        let nominal = sample(&inst, 16, None).unwrap();
        assert_eq!(nominal.bbox, inst.region.as_ref().unwrap().nominal);
        assert_eq!(nominal.crop.len(), 16 * 16 * 3);
    }
}
