//! The RGB model's input: the colour around each instance's box, kept at load time, and the
//! crops cut from it per batch — the nominal box for evaluation, a jittered box (and jittered
//! colours) for training, so that the model does not rely on a perfect detector.
//!
//! Boxes are square (the longer side of `bbox_visib` times [`CONTEXT`], centred on it), so a
//! crop shows the object undistorted and its side in pixels says how far the object is.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use synthgen_core::rng::splitmix64;

use crate::data::Instance;
use crate::models::rgb::{Pinhole, SquareBox};

pub use crate::region::{nominal_box, BoxRegion, CoordRegion, CONTEXT, STORED_CONTEXT};

/// Training jitter of the box: its centre moves by up to this fraction of its side in x and
/// in y, independently...
pub const JITTER_SHIFT: f64 = 0.15;
/// ...and its side is scaled by a factor in 1 ± this.
pub const JITTER_SCALE: f64 = 0.2;
// The jittered crop stays inside the stored region: CONTEXT · ((1 + JITTER_SCALE) / 2 +
// JITTER_SHIFT) = 0.9375 ≤ STORED_CONTEXT / 2.
const _: () =
    assert!(CONTEXT * ((1.0 + JITTER_SCALE) / 2.0 + JITTER_SHIFT) <= STORED_CONTEXT / 2.0);

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
    blur_and_noise(crop, size, size, &mut rng);
}

/// With probability 1/3 a 3×3 box blur, then Gaussian-like noise of 0–6 levels (the sum of
/// three uniforms), of a `w × h` RGB image in place.
fn blur_and_noise(img: &mut [u8], w: u32, h: u32, rng: &mut ChaCha8Rng) {
    let (w, h) = (w as usize, h as usize);
    if rng.gen_bool(1.0 / 3.0) {
        let src = img.to_vec();
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let mut sum = 0u32;
                    let mut n = 0u32;
                    for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                        for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                            sum += u32::from(src[(yy * w + xx) * 3 + c]);
                            n += 1;
                        }
                    }
                    img[(y * w + x) * 3 + c] = ((sum + n / 2) / n) as u8;
                }
            }
        }
    }
    let sigma = rng.gen_range(0.0..=6.0);
    if sigma > 0.5 {
        for v in img.iter_mut() {
            let e: f64 = (0..3).map(|_| rng.gen_range(-1.0..=1.0)).sum::<f64>() * sigma;
            *v = (f64::from(*v) + e).round().clamp(0.0, 255.0) as u8;
        }
    }
}

/// The RGB models' photometric augmentation of a whole `w × h` image (the detector's
/// training frames): the colour jitter of the crops, then [`dense_augment`]'s blur and noise.
pub fn photometric_augment(img: &mut [u8], w: u32, h: u32, rng: &mut ChaCha8Rng) {
    jitter_colours(img, rng);
    blur_and_noise(img, w, h, rng);
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
    use crate::region::{crop_resize, edge_rect};

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
