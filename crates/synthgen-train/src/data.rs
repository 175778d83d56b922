//! From a dataset (BOP or Linemod, through [`FrameSource`]) to training instances: per
//! annotated object, N points sampled from the visible mask's valid depth and back-projected
//! to metres (camera frame), an optional RGB crop around `bbox_visib`, for the RGB model the
//! colour around the box ([`BoxRegion`]) instead of the points, and the GT pose.
//! Loaded in parallel, kept in memory.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use synthgen_core::rng::splitmix64;
use synthgen_core::{GtInfo, Pose, Progress};
use synthgen_formats::bop::{read_depth_m, read_rgb_sized, Plane, RgbImage};
use synthgen_formats::layout::open_source;
use synthgen_formats::source::{FrameSource, SourceFrame};

use crate::error::{Error, Result};
use crate::models::rgb::Pinhole;
use crate::models::rgb_dense::dense_out;
use crate::region::{crop_resize, BoxRegion, CoordRegion, CONTEXT, STORED_CONTEXT};

/// How instances are made.
#[derive(Debug, Clone, PartialEq)]
pub struct DataOptions {
    /// Points sampled per instance (with replacement when fewer valid pixels).
    pub n_points: usize,
    /// Instances with `visib_fract` below this are left out.
    pub min_visib_fract: f64,
    /// Instances with fewer valid (masked, with depth) pixels are skipped and counted.
    pub min_pixels: usize,
    /// Side of the square RGB crop; 0 loads no RGB at all (TNet needs none).
    pub crop_size: u32,
    /// Side of the RGB model's input crop; > 0 keeps each instance's [`BoxRegion`].
    pub rgb_box: u32,
    /// With `rgb_box`: the dense RGB model's targets ([`CoordRegion`], `rgb_box / 2` cells
    /// across the nominal crop) from the frames' depth, where a frame has depth.
    pub dense_targets: bool,
    /// Sample points from the depth (every model but RGB). Without, no depth image is read
    /// and the valid pixels are the visible mask's.
    pub depth_points: bool,
    pub seed: u64,
    /// The split to read; `None` picks `test`, else the only split.
    pub split: Option<String>,
    /// Perturbations of the visible pixels, for training on synthetic frames (none: the
    /// instances as rendered).
    pub augment: Augment,
    /// Boxes the RGB models' crops come from instead of the GT visible boxes (a detector's);
    /// an instance without one is left out (counted in `skipped_undetected`).
    pub crop_boxes: Option<std::sync::Arc<CropBoxes>>,
    /// Masks the instances' pixels come from instead of the GT visible masks (a detector's:
    /// the depth models without GT masks); an instance without one is left out (counted in
    /// `skipped_undetected`).
    pub crop_masks: Option<std::sync::Arc<CropMasks>>,
}

/// Per (scene, image, object), visible masks of the frame's size, best first, as
/// [`CropBoxes`]: the `k`-th instance of an object in an image reads its pixels from the
/// `k`-th mask.
pub type CropMasks = BTreeMap<(u32, u32, u32), Vec<synthgen_formats::coco::Rle>>;

/// Per (scene, image, object), boxes `[x, y, w, h]` read as `bbox_visib` (last pixel
/// `x + w`), best first: the `k`-th instance of an object in an image (in GT order, among
/// those loaded) is cropped from its `k`-th box. Which box goes with which instance does not
/// matter: the estimates are matched to the GT when scored.
pub type CropBoxes = BTreeMap<(u32, u32, u32), Vec<[f64; 4]>>;

/// Perturbations of each instance's visible pixels before its points are drawn, toward what
/// real frames give a model that synthetic ones do not: a segmenter's mask boundary, bleeding
/// onto the background or falling short of the object; occluders the renders lack; missing
/// readings. Drawn per instance from its own RNG stream (a pure function of the seed and the
/// instance). The default changes nothing.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Augment {
    /// The visible mask grows or shrinks by a whole number of pixels drawn uniformly in
    /// −k..=k (grown pixels take the depth there: the background behind an edge).
    pub mask_jitter_px: u32,
    /// Probability that an instance loses the pixels beyond a random line (10–50 % of them).
    pub occlusion_prob: f64,
    /// Up to this share of the visible pixels is dropped at random (0..1).
    pub dropout: f64,
    /// The visible mask moves by whole pixels drawn uniformly in −k..=k along x and y (a mask
    /// registered to the colour image, read against a depth image a few pixels off).
    pub mask_shift_px: u32,
}

impl Augment {
    pub fn is_none(&self) -> bool {
        *self == Augment::default()
    }
}

impl Default for DataOptions {
    fn default() -> Self {
        Self {
            n_points: 500,
            min_visib_fract: 0.1,
            min_pixels: 50,
            crop_size: 0,
            rgb_box: 0,
            dense_targets: false,
            depth_points: true,
            seed: 0,
            split: None,
            augment: Augment::default(),
            crop_boxes: None,
            crop_masks: None,
        }
    }
}

/// One annotated object instance, ready for the models.
#[derive(Debug, Clone, PartialEq)]
pub struct Instance {
    pub scene_id: u32,
    pub im_id: u32,
    pub gt_id: usize,
    pub obj_id: u32,
    /// `n_points` back-projected points, metres, camera frame.
    pub points_m: Vec<[f32; 3]>,
    /// The sampled pixels' positions in the crop (x, y in 0..crop_size); empty without crops.
    pub crop_xy: Vec<[f32; 2]>,
    /// `crop_size² × 3` bytes, RGB, row-major; empty without crops.
    pub crop_rgb: Vec<u8>,
    /// The colour around the visible box (the RGB model); `None` without `rgb_box`.
    pub region: Option<BoxRegion>,
    /// GT `cam_from_obj`; its translation is the centre TNet predicts.
    pub pose: Pose,
}

impl Instance {
    /// The frame the instance belongs to (train/val splits are by frame).
    pub fn frame(&self) -> (u32, u32) {
        (self.scene_id, self.im_id)
    }
}

/// The loaded instances and what was left out.
#[derive(Debug, Clone, Default)]
pub struct InstanceSet {
    pub instances: Vec<Instance>,
    pub split: String,
    pub frames: usize,
    pub skipped_low_visib: usize,
    pub skipped_few_pixels: usize,
    /// Instances without a box in [`DataOptions::crop_boxes`].
    pub skipped_undetected: usize,
}

impl InstanceSet {
    pub fn obj_ids(&self) -> BTreeSet<u32> {
        self.instances.iter().map(|i| i.obj_id).collect()
    }
}

/// The RNG of one instance: a pure function of (seed, scene, image, gt id).
fn instance_rng(seed: u64, scene_id: u32, im_id: u32, gt_id: usize) -> ChaCha8Rng {
    let s = splitmix64(splitmix64(splitmix64(seed) ^ u64::from(scene_id)) ^ u64::from(im_id));
    ChaCha8Rng::seed_from_u64(splitmix64(s ^ gt_id as u64))
}

/// `n` indices into `0..len`: without replacement when `len >= n`, else with replacement.
fn sample_indices(rng: &mut ChaCha8Rng, len: usize, n: usize) -> Vec<usize> {
    if len >= n {
        sample(rng, len, n).into_vec()
    } else {
        (0..n).map(|_| rng.gen_range(0..len)).collect()
    }
}

/// The split to evaluate: `wanted`, else `test` when present, else the only split.
pub fn pick_split(ds: &dyn FrameSource, wanted: Option<&str>) -> Result<String> {
    let splits = ds.splits();
    if let Some(w) = wanted {
        if splits.iter().any(|s| s == w) {
            return Ok(w.to_string());
        }
        return Err(Error::InvalidOption(format!(
            "split {w:?} not found in {} (splits: {})",
            ds.root().display(),
            splits.join(", ")
        )));
    }
    if splits.iter().any(|s| s == "test") {
        return Ok("test".into());
    }
    match splits.as_slice() {
        [only] => Ok(only.clone()),
        [] => Err(Error::NoInstances {
            reason: "no split with frames".into(),
            path: ds.root().to_path_buf(),
        }),
        many => Err(Error::InvalidOption(format!(
            "dataset has several splits ({}); choose one with --split",
            many.join(", ")
        ))),
    }
}

/// Cells across the stored region of the dense targets for an `rgb_box`-pixel crop: two
/// per output cell of the model ([`dense_out`] across the nominal crop), so that cutting a
/// jittered crop from them moves a target by at most a quarter of an output cell.
pub fn dense_target_res(rgb_box: u32) -> u32 {
    2 * (f64::from(dense_out(rgb_box)) * STORED_CONTEXT / CONTEXT).ceil() as u32
}

/// A sampled pixel: u, v and its index in the image.
type Pixel = (f64, f64, usize);

enum Outcome {
    Instance(Box<Instance>),
    LowVisib,
    FewPixels,
    Undetected,
}

/// The detection (box or mask) for the next instance of `key`'s object in its image: the
/// `k`-th of `detections[key]` for the object's `k`-th instance met (`rank` counts them).
fn ranked<'a, T>(
    detections: &'a BTreeMap<(u32, u32, u32), Vec<T>>,
    rank: &mut BTreeMap<u32, usize>,
    key: (u32, u32, u32),
) -> Option<&'a T> {
    let r = rank.entry(key.2).or_insert(0);
    *r += 1;
    detections.get(&key).and_then(|v| v.get(*r - 1))
}

fn load_frame(frame: &SourceFrame, size: [u32; 2], opts: &DataOptions) -> Result<Vec<Outcome>> {
    let gts = &frame.gt;
    if gts.is_empty() {
        return Ok(Vec::new());
    }
    let (scene_id, im_id) = (frame.location.scene_id, frame.location.im_id);
    let cam = &frame.camera;
    let infos: Option<&Vec<GtInfo>> = frame.gt_info.as_ref();
    let wanted: Vec<usize> = (0..gts.len())
        .filter(|&g| {
            infos.and_then(|i| i.get(g)).map_or(1.0, |i| i.visib_fract) >= opts.min_visib_fract
        })
        .collect();
    let mut out: Vec<Outcome> = (0..gts.len() - wanted.len())
        .map(|_| Outcome::LowVisib)
        .collect();
    if wanted.is_empty() {
        return Ok(out);
    }
    let dense = opts.dense_targets && opts.rgb_box > 0;
    let depth = if dense && !opts.depth_points {
        frame
            .depth
            .as_ref()
            .map(|p| read_depth_m(p, cam.depth_scale))
            .transpose()?
    } else if opts.depth_points {
        let depth_path = frame.depth.as_ref().ok_or_else(|| Error::Malformed {
            what: "dataset",
            message: format!("image {im_id} of scene {scene_id} has no depth image"),
            path: frame.rgb.clone(),
        })?;
        Some(read_depth_m(depth_path, cam.depth_scale)?)
    } else {
        None
    };
    let rgb = if opts.crop_size > 0 || opts.rgb_box > 0 {
        Some(read_rgb_sized(&frame.rgb, size)?)
    } else {
        None
    };
    // Per object, the instances met so far: the rank of its crop box and of its mask.
    let mut rank: BTreeMap<u32, usize> = BTreeMap::new();
    let mut mask_rank: BTreeMap<u32, usize> = BTreeMap::new();
    for gt_id in wanted {
        let key = (scene_id, im_id, gts[gt_id].obj_id);
        let detected_mask = match &opts.crop_masks {
            Some(masks) => match ranked(masks, &mut mask_rank, key) {
                Some(m) => Some(m),
                None => {
                    out.push(Outcome::Undetected);
                    continue;
                }
            },
            None => None,
        };
        let detected = match &opts.crop_boxes {
            Some(boxes) => match ranked(boxes, &mut rank, key) {
                Some(b) => Some(*b),
                None => {
                    out.push(Outcome::Undetected);
                    continue;
                }
            },
            None => None,
        };
        // No visible mask (a Linemod object without a folder entry for the frame): no
        // visible pixels; except for the RGB models on a dataset without masks and depth
        // (Linemod-Occluded's BOP test images): they read only the colour inside
        // `bbox_visib`, and `px_count_visib` says how much of the object shows.
        let mask_ref = frame.masks_visib.get(gt_id).and_then(Option::as_ref);
        let info = infos.and_then(|i| i.get(gt_id));
        let box_only = match (mask_ref, info, &rgb) {
            (None, Some(i), Some(img))
                if !opts.depth_points && opts.crop_size == 0 && depth.is_none() =>
            {
                (i.bbox_visib[2] > 0 && i.bbox_visib[3] > 0).then_some((i, img))
            }
            _ => None,
        };
        let (mask, mask_path) = match (detected_mask, mask_ref, box_only) {
            (Some(m), _, _) => (rle_plane(m), frame.rgb.clone()),
            (None, Some(m), _) => (m.read()?, m.path().to_path_buf()),
            (None, None, Some((i, img))) => {
                if (i.px_count_visib as usize) < opts.min_pixels.max(1) {
                    out.push(Outcome::FewPixels);
                    continue;
                }
                // The box as the mask: only its bounding box is read, and no dense targets
                // come from it (they need depth, which such a frame lacks).
                let plane = box_plane(img.width, img.height, i.bbox_visib.map(f64::from));
                (plane, frame.rgb.clone())
            }
            (None, None, None) => {
                out.push(Outcome::FewPixels);
                continue;
            }
        };
        let bbox_hint = detected.or_else(|| {
            infos
                .and_then(|i| i.get(gt_id))
                .map(|i| i.bbox_visib)
                .filter(|b| b[2] > 0 && b[3] > 0)
                .map(|b| b.map(f64::from))
        });
        let pixels = FramePixels {
            scene_id,
            im_id,
            cam_k: &cam.cam_k,
            rgb: rgb.as_ref(),
            depth: depth.as_ref(),
        };
        out.push(
            match build_instance(
                &pixels,
                InstanceKey {
                    gt_id,
                    obj_id: gts[gt_id].obj_id,
                },
                &mask,
                &mask_path,
                bbox_hint,
                Some(gts[gt_id].cam_from_obj()),
                opts,
            )? {
                Some(i) => Outcome::Instance(Box::new(i)),
                None => Outcome::FewPixels,
            },
        );
    }
    Ok(out)
}

/// A COCO RLE mask as a mask image (0 or 255).
fn rle_plane(m: &synthgen_formats::coco::Rle) -> Plane<u8> {
    Plane {
        width: m.width,
        height: m.height,
        data: m.decode().into_iter().map(|v| v * 255).collect(),
    }
}

/// A `width × height` mask image of the pixels of box `[x, y, w, h]` (whole pixels from
/// `floor(x)` to `floor(x) + floor(w)`, as `bbox_visib`'s, clipped to the image).
fn box_plane(width: u32, height: u32, b: [f64; 4]) -> Plane<u8> {
    let [x, y, bw, bh] = b.map(|v| v.max(0.0) as u32);
    let mut data = vec![0u8; (width * height) as usize];
    for yy in y..y.saturating_add(bh).min(height) {
        for xx in x..x.saturating_add(bw).min(width) {
            data[(yy * width + xx) as usize] = 255;
        }
    }
    Plane {
        width,
        height,
        data,
    }
}

/// The instance a detection gives, in a frame with no GT: its pixels are the detection's mask
/// where it has one, else its box `[x, y, w, h]` (the RGB models read only the colour around
/// the box); the RGB models' region and crops come from the box. None when fewer than
/// `min_pixels` pixels are valid. The instance's pose is the identity (unknown).
pub fn detection_instance(
    f: &FramePixels<'_>,
    key: InstanceKey,
    bbox: [f64; 4],
    mask: Option<&synthgen_formats::coco::Rle>,
    source: &Path,
    opts: &DataOptions,
) -> Result<Option<Instance>> {
    let plane = match mask {
        Some(m) => rle_plane(m),
        None => {
            let (w, h) = f
                .rgb
                .map(|i| (i.width, i.height))
                .or(f.depth.map(|d| (d.width, d.height)))
                .ok_or_else(|| Error::InvalidOption("a frame needs its colour or depth".into()))?;
            box_plane(w, h, bbox)
        }
    };
    build_instance(f, key, &plane, source, Some(bbox), None, opts)
}

/// A frame's images and camera, as the instances of it are made from them.
pub struct FramePixels<'a> {
    pub scene_id: u32,
    pub im_id: u32,
    /// The camera matrix, row-major (BOP's `cam_K`).
    pub cam_k: &'a [f64; 9],
    /// The colour, when the model reads it (crops, regions).
    pub rgb: Option<&'a RgbImage>,
    /// The depth in metres, when the model reads it (points; the dense targets).
    pub depth: Option<&'a Plane<f32>>,
}

/// Which instance of a frame: its index (the GT id, or the detection's rank among the
/// frame's) and its object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InstanceKey {
    pub gt_id: usize,
    pub obj_id: u32,
}

/// One instance from its visible pixels (`mask`, the frame's size; `mask_path` names it in
/// errors): points from the mask's valid depth, the RGB crop and the RGB model's region around
/// `bbox_hint` (`[x, y, w, h]`; the valid pixels' bounding box when None), the dense targets
/// when `gt_pose` is known. None when fewer than `min_pixels` pixels are valid. The instance's
/// pose is `gt_pose`, the identity when unknown (frames with no GT: `synthgen predict`).
pub fn build_instance(
    f: &FramePixels<'_>,
    key: InstanceKey,
    mask: &Plane<u8>,
    mask_path: &Path,
    bbox_hint: Option<[f64; 4]>,
    gt_pose: Option<Pose>,
    opts: &DataOptions,
) -> Result<Option<Instance>> {
    let (scene_id, im_id, gt_id) = (f.scene_id, f.im_id, key.gt_id);
    let [fx, _, cx, _, fy, cy, ..] = *f.cam_k;
    let dense = opts.dense_targets && opts.rgb_box > 0;
    let depth = f.depth;
    // Without depth_points the depth serves the dense targets only, never the pixels.
    let pixel_depth = depth.filter(|_| opts.depth_points);
    let rgb = f.rgb;
    if let Some(depth) = depth {
        if mask.width != depth.width || mask.height != depth.height {
            return Err(Error::Malformed {
                what: "mask",
                message: format!(
                    "size {}x{} differs from the depth image's {}x{}",
                    mask.width, mask.height, depth.width, depth.height
                ),
                path: mask_path.to_path_buf(),
            });
        }
    }
    let w = mask.width as usize;
    let mut in_mask: Vec<bool> = mask.data.iter().map(|&v| v > 0).collect();
    if !opts.augment.is_none() {
        let mut rng = instance_rng(opts.seed ^ AUGMENT_STREAM, scene_id, im_id, gt_id);
        augment_mask(&mut in_mask, w, &opts.augment, &mut rng);
    }
    let valid: Vec<usize> = (0..in_mask.len())
        .filter(|&i| in_mask[i] && pixel_depth.is_none_or(|d| d.data[i] > 0.0))
        .collect();
    if valid.len() < opts.min_pixels.max(1) {
        return Ok(None);
    }
    // The sampled pixels (u, v, index) and their back-projected points; none without depth.
    let (uv, points_m): (Vec<Pixel>, Vec<[f32; 3]>) = match pixel_depth {
        Some(depth) => {
            let mut rng = instance_rng(opts.seed, scene_id, im_id, gt_id);
            let uv: Vec<Pixel> = sample_indices(&mut rng, valid.len(), opts.n_points)
                .iter()
                .map(|&k| {
                    let i = valid[k];
                    ((i % w) as f64, (i / w) as f64, i)
                })
                .collect();
            let points = uv
                .iter()
                .map(|&(u, v, i)| {
                    let z = f64::from(depth.data[i]);
                    [
                        ((u - cx) * z / fx) as f32,
                        ((v - cy) * z / fy) as f32,
                        z as f32,
                    ]
                })
                .collect();
            (uv, points)
        }
        None => (Vec::new(), Vec::new()),
    };
    // The detector's box; else bbox_visib when known, else the bounding box of the valid
    // pixels.
    let bbox = || {
        bbox_hint.unwrap_or_else(|| {
            let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, 0.0f64, 0.0f64);
            for &i in &valid {
                let (u, v) = ((i % w) as f64, (i / w) as f64);
                (x0, y0, x1, y1) = (x0.min(u), y0.min(v), x1.max(u), y1.max(v));
            }
            [x0, y0, (x1 - x0).max(1.0), (y1 - y0).max(1.0)]
        })
    };
    let region = match rgb {
        Some(img) if opts.rgb_box > 0 => {
            let mut r = BoxRegion::from_image(
                &img.rgb,
                img.width,
                img.height,
                bbox(),
                opts.rgb_box,
                Pinhole::from_cam_k(f.cam_k),
            );
            if let (true, Some(d), Some(pose)) = (dense, depth, gt_pose) {
                // The visible (unperturbed) mask's pixels, back-projected and taken to
                // the model frame.
                let obj_from_cam = pose.inverse();
                let at = |x: usize, y: usize| {
                    let i = y * w + x;
                    let z = f64::from(d.data[i]);
                    if mask.data[i] == 0 || z <= 0.0 || !z.is_finite() {
                        return [f32::NAN; 3];
                    }
                    let c = synthgen_core::glam::DVec3::new(
                        (x as f64 - cx) * z / fx,
                        (y as f64 - cy) * z / fy,
                        z,
                    );
                    obj_from_cam.transform_point(c).as_vec3().to_array()
                };
                let res = dense_target_res(opts.rgb_box);
                r.target = Some(CoordRegion::sample(
                    at,
                    mask.width,
                    mask.height,
                    &r.region,
                    res,
                ));
            }
            Some(r)
        }
        _ => None,
    };
    let (crop_xy, crop_rgb) = match rgb {
        Some(img) if opts.crop_size > 0 => {
            let bbox = bbox();
            let s = f64::from(opts.crop_size);
            let xy = uv
                .iter()
                .map(|&(u, v, _)| {
                    [
                        (((u - bbox[0]) / bbox[2]) * s).clamp(0.0, s - 1.0) as f32,
                        (((v - bbox[1]) / bbox[3]) * s).clamp(0.0, s - 1.0) as f32,
                    ]
                })
                .collect();
            (
                xy,
                crop_resize(&img.rgb, img.width, img.height, bbox, opts.crop_size),
            )
        }
        _ => (Vec::new(), Vec::new()),
    };
    Ok(Some(Instance {
        scene_id,
        im_id,
        gt_id,
        obj_id: key.obj_id,
        points_m,
        crop_xy,
        crop_rgb,
        region,
        pose: gt_pose.unwrap_or(Pose::IDENTITY),
    }))
}

/// Seeds the augmentation's per-instance streams apart from the point sampling's.
const AUGMENT_STREAM: u64 = 0xa06e_17a7_e5ee_d000;

/// Applies `a` to a visible mask (`width` pixels a row), in place.
fn augment_mask(mask: &mut [bool], width: usize, a: &Augment, rng: &mut ChaCha8Rng) {
    let h = mask.len() / width.max(1);
    if a.mask_jitter_px > 0 {
        let k = rng.gen_range(-(a.mask_jitter_px as i64)..=a.mask_jitter_px as i64);
        for _ in 0..k.unsigned_abs() {
            let grow = k > 0;
            let before = mask.to_vec();
            for y in 0..h {
                for x in 0..width {
                    let i = y * width + x;
                    let n = [
                        (x > 0).then(|| before[i - 1]),
                        (x + 1 < width).then(|| before[i + 1]),
                        (y > 0).then(|| before[i - width]),
                        (y + 1 < h).then(|| before[i + width]),
                    ];
                    if grow {
                        mask[i] = before[i] || n.iter().flatten().any(|&v| v);
                    } else {
                        mask[i] = before[i] && n.iter().all(|v| v.unwrap_or(false));
                    }
                }
            }
        }
    }
    if a.mask_shift_px > 0 {
        let k = a.mask_shift_px as i64;
        let (dx, dy) = (rng.gen_range(-k..=k), rng.gen_range(-k..=k));
        let before = mask.to_vec();
        for y in 0..h as i64 {
            for x in 0..width as i64 {
                let (sx, sy) = (x - dx, y - dy);
                mask[(y as usize) * width + x as usize] = (0..width as i64).contains(&sx)
                    && (0..h as i64).contains(&sy)
                    && before[(sy as usize) * width + sx as usize];
            }
        }
    }
    if a.occlusion_prob > 0.0 && rng.gen::<f64>() < a.occlusion_prob {
        let pts: Vec<(f64, f64)> = (0..mask.len())
            .filter(|&i| mask[i])
            .map(|i| ((i % width) as f64, (i / width) as f64))
            .collect();
        if pts.len() > 10 {
            // A line at a random angle, placed so that 10–50 % of the pixels lie beyond it.
            let angle = rng.gen_range(0.0..std::f64::consts::TAU);
            let (dx, dy) = (angle.cos(), angle.sin());
            let mut proj: Vec<f64> = pts.iter().map(|p| p.0 * dx + p.1 * dy).collect();
            proj.sort_by(f64::total_cmp);
            let cut = proj[((1.0 - rng.gen_range(0.1..0.5)) * (proj.len() - 1) as f64) as usize];
            for (i, m) in mask.iter_mut().enumerate() {
                let (x, y) = ((i % width) as f64, (i / width) as f64);
                if *m && x * dx + y * dy > cut {
                    *m = false;
                }
            }
        }
    }
    if a.dropout > 0.0 {
        let p = rng.gen_range(0.0..=a.dropout);
        for m in mask.iter_mut() {
            if *m && rng.gen::<f64>() < p {
                *m = false;
            }
        }
    }
}

/// Loads every instance of a split (frames in parallel), in (scene, image, gt) order, from a
/// dataset folder in either layout (BOP or Linemod, detected).
pub fn load_instances(
    root: &Path,
    opts: &DataOptions,
    progress: &dyn Progress,
) -> Result<InstanceSet> {
    let source = open_source(root)?;
    load_source_instances(source.as_ref(), opts, progress)
}

/// [`load_instances`] from an opened dataset.
pub fn load_source_instances(
    source: &dyn FrameSource,
    opts: &DataOptions,
    progress: &dyn Progress,
) -> Result<InstanceSet> {
    if opts.depth_points && opts.n_points == 0 {
        return Err(Error::InvalidOption(
            "the number of points must be positive".into(),
        ));
    }
    let split = pick_split(source, opts.split.as_deref())?;
    let jobs = source.frames(std::slice::from_ref(&split))?;
    let cam = source.camera();
    progress.start("loading", jobs.len() as u64);
    let per_frame: Vec<Vec<Outcome>> = jobs
        .par_iter()
        .map(|frame| {
            let r = load_frame(frame, [cam.width, cam.height], opts);
            progress.advance(1);
            r
        })
        .collect::<Result<_>>()?;
    progress.finish();
    let mut set = InstanceSet {
        split,
        frames: jobs.len(),
        ..InstanceSet::default()
    };
    for o in per_frame.into_iter().flatten() {
        match o {
            Outcome::Instance(i) => set.instances.push(*i),
            Outcome::LowVisib => set.skipped_low_visib += 1,
            Outcome::FewPixels => set.skipped_few_pixels += 1,
            Outcome::Undetected => set.skipped_undetected += 1,
        }
    }
    Ok(set)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn a_detection_gives_its_masks_points_or_its_boxs_colour() {
        use synthgen_formats::coco::Rle;
        // A 40 × 30 frame 2 m away everywhere, but a hole in the depth at (5, 5).
        let (w, h) = (40u32, 30u32);
        let mut depth = Plane {
            width: w,
            height: h,
            data: vec![2.0f32; (w * h) as usize],
        };
        depth.data[(5 * w + 5) as usize] = 0.0;
        let rgb = RgbImage {
            width: w,
            height: h,
            rgb: vec![90; (w * h * 3) as usize],
        };
        let k = [100.0, 0.0, 20.0, 0.0, 100.0, 15.0, 0.0, 0.0, 1.0];
        let frame = FramePixels {
            scene_id: 0,
            im_id: 3,
            cam_k: &k,
            rgb: Some(&rgb),
            depth: Some(&depth),
        };
        let rect = |x0: u32, y0: u32, x1: u32, y1: u32| {
            let mut m = vec![0u8; (w * h) as usize];
            for y in y0..y1 {
                for x in x0..x1 {
                    m[(y * w + x) as usize] = 1;
                }
            }
            Rle::from_mask(&m, w, h)
        };
        let key = InstanceKey {
            gt_id: 0,
            obj_id: 7,
        };
        let opts = DataOptions {
            n_points: 64,
            min_pixels: 20,
            ..DataOptions::default()
        };
        let src = Path::new("frame.png");
        // Points from the mask's pixels with depth: x in 0..10, y in 0..10, hole left out.
        let m = rect(0, 0, 10, 10);
        let i = detection_instance(&frame, key, [0.0, 0.0, 9.0, 9.0], Some(&m), src, &opts)
            .unwrap()
            .unwrap();
        assert_eq!((i.obj_id, i.im_id, i.points_m.len()), (7, 3, 64));
        assert_eq!(i.pose, Pose::IDENTITY);
        for p in &i.points_m {
            assert!((p[2] - 2.0).abs() < 1e-6);
            let (u, v) = (p[0] * 100.0 / 2.0 + 20.0, p[1] * 100.0 / 2.0 + 15.0);
            assert!(
                (-0.01..9.01).contains(&u) && (-0.01..9.01).contains(&v),
                "{p:?}"
            );
            assert!(
                (u - 5.0).abs() > 1e-3 || (v - 5.0).abs() > 1e-3,
                "the hole: {p:?}"
            );
        }
        // Too few valid pixels: no instance.
        let small = rect(0, 0, 4, 4);
        assert!(
            detection_instance(&frame, key, [0.0, 0.0, 3.0, 3.0], Some(&small), src, &opts)
                .unwrap()
                .is_none()
        );
        // The RGB models: no mask, the region around the box.
        let rgb_opts = DataOptions {
            rgb_box: 16,
            depth_points: false,
            min_pixels: 1,
            ..DataOptions::default()
        };
        let i = detection_instance(&frame, key, [10.0, 8.0, 12.0, 10.0], None, src, &rgb_opts)
            .unwrap()
            .unwrap();
        assert!(i.points_m.is_empty());
        let r = i.region.expect("a region around the box");
        assert_eq!(r, {
            let pixels = FramePixels {
                depth: None,
                ..frame
            };
            build_instance(
                &pixels,
                key,
                &box_plane(w, h, [10.0, 8.0, 12.0, 10.0]),
                src,
                Some([10.0, 8.0, 12.0, 10.0]),
                None,
                &rgb_opts,
            )
            .unwrap()
            .unwrap()
            .region
            .unwrap()
        });
    }

    #[test]
    fn sampling_is_deterministic_and_fills_up() {
        let mut a = instance_rng(1, 0, 5, 0);
        let mut b = instance_rng(1, 0, 5, 0);
        assert_eq!(
            sample_indices(&mut a, 1000, 10),
            sample_indices(&mut b, 1000, 10)
        );
        let mut c = instance_rng(1, 0, 5, 1);
        let few = sample_indices(&mut c, 3, 10);
        assert_eq!(few.len(), 10);
        assert!(few.iter().all(|&i| i < 3));
        let mut d = instance_rng(1, 0, 5, 2);
        let mut distinct = sample_indices(&mut d, 20, 20);
        distinct.sort_unstable();
        assert_eq!(distinct, (0..20).collect::<Vec<_>>());
    }

    #[test]
    fn crop_of_uniform_region_keeps_colour() {
        let (w, h) = (8u32, 6u32);
        let mut rgb = vec![0u8; (w * h * 3) as usize];
        for y in 2..5 {
            for x in 3..7 {
                let i = ((y * w + x) * 3) as usize;
                rgb[i..i + 3].copy_from_slice(&[200, 100, 50]);
            }
        }
        let c = crop_resize(&rgb, w, h, [3.5, 2.5, 2.0, 1.5], 4);
        assert_eq!(c.len(), 4 * 4 * 3);
        assert!(c.chunks(3).all(|p| p == [200, 100, 50]), "{c:?}");
    }

    /// The training-time mask perturbations: jitter grows or shrinks by whole pixels, the
    /// shift moves the mask, occlusion cuts a share beyond a line, dropout thins it; the
    /// default changes nothing.
    #[test]
    fn mask_augmentations_do_what_they_say() {
        use rand::SeedableRng;
        let (w, h) = (20usize, 20usize);
        let square = || -> Vec<bool> {
            (0..w * h)
                .map(|i| (5..15).contains(&(i % w)) && (5..15).contains(&(i / w)))
                .collect()
        };
        let count = |m: &[bool]| m.iter().filter(|&&v| v).count();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut m = square();
        augment_mask(&mut m, w, &Augment::default(), &mut rng);
        assert_eq!(m, square());
        let mut sizes = std::collections::BTreeSet::new();
        for _ in 0..40 {
            let mut m = square();
            let a = Augment {
                mask_jitter_px: 1,
                ..Augment::default()
            };
            augment_mask(&mut m, w, &a, &mut rng);
            sizes.insert(count(&m));
        }
        // Shrunk by one (8x8), as is, grown by one (a 12x12 cross-shaped dilation: 140).
        assert_eq!(sizes.into_iter().collect::<Vec<_>>(), [64, 100, 140]);
        for _ in 0..20 {
            let mut m = square();
            let a = Augment {
                mask_shift_px: 3,
                ..Augment::default()
            };
            augment_mask(&mut m, w, &a, &mut rng);
            assert_eq!(
                count(&m),
                100,
                "inside the image, a shift keeps every pixel"
            );
            let xs: Vec<usize> = (0..w * h).filter(|&i| m[i]).map(|i| i % w).collect();
            let x0 = *xs.iter().min().unwrap();
            assert!((2..=8).contains(&x0), "{x0}");
        }
        let mut m = square();
        let a = Augment {
            occlusion_prob: 1.0,
            ..Augment::default()
        };
        augment_mask(&mut m, w, &a, &mut rng);
        assert!((45..=92).contains(&count(&m)), "{}", count(&m));
        let mut m = square();
        let a = Augment {
            dropout: 0.5,
            ..Augment::default()
        };
        augment_mask(&mut m, w, &a, &mut rng);
        assert!(count(&m) >= 40 && m.iter().zip(square()).all(|(a, b)| !*a || b));
    }
}
