//! Masks and `scene_gt_info` of real frames from their GT poses, as bop_toolkit's
//! `calc_gt_masks` / `calc_gt_info` compute them: every object rendered alone at its pose
//! (by a [`PoseRenderer`]), the "bop19" visibility test against the frame's own depth image
//! when it has one, else against the rendered scene depth. And the comparison of such masks
//! with masks a dataset already has (its authors' labels).

use synthgen_core::annotate::{
    annotate, mask_bbox, silhouette_bbox, ObjectAnnotation, DEFAULT_VISIB_DELTA_M,
};
use synthgen_core::{GtInfo, Intrinsics, PoseRenderer, RenderedFrame};

use std::path::Path;

use crate::bop::image::{encode_gray8_png, read_depth_m, read_depth_raw, RgbImage};
use crate::bop::PngCompression;
use crate::draw::Canvas;
use crate::error::{Error, Result};
use crate::io::{atomic_write, create_dir_all};
use crate::source::SourceFrame;

/// One frame's objects rendered at their GT poses and the annotations computed from them.
#[derive(Debug, Clone)]
pub struct FrameAnnotations {
    /// The objects alone and together (instance `i + 1` = gt `i`).
    pub rendered: RenderedFrame,
    /// Per gt id.
    pub objects: Vec<ObjectAnnotation>,
    /// Whether the visibility test used the frame's depth image (else the rendered depth).
    pub real_depth: bool,
}

/// The intrinsics of a frame: its `cam_K` at the given image size.
pub fn frame_intrinsics(frame: &SourceFrame, width: u32, height: u32) -> Intrinsics {
    frame.camera.intrinsics(width, height)
}

/// A frame's annotated objects rendered at their GT poses (instance `i + 1` = gt `i`), with
/// the camera `k`; an object without a model is an error naming the frame.
pub fn render_gt(
    renderer: &dyn PoseRenderer,
    frame: &SourceFrame,
    k: &Intrinsics,
) -> Result<RenderedFrame> {
    let objects: Vec<_> = frame
        .gt
        .iter()
        .map(|g| (g.obj_id, g.cam_from_obj()))
        .collect();
    renderer.render_poses(k, &objects).map_err(|m| {
        Error::InvalidRequest(format!(
            "cannot render {}/{:06} image {}: {m}",
            frame.location.split, frame.location.scene_id, frame.location.im_id
        ))
    })
}

/// Renders a frame's objects at their GT poses and annotates them (see the module doc).
/// `width` x `height` is the image size; a depth image of another size is an error naming it.
pub fn annotate_frame(
    renderer: &dyn PoseRenderer,
    frame: &SourceFrame,
    width: u32,
    height: u32,
    delta_m: f32,
) -> Result<FrameAnnotations> {
    let k = frame_intrinsics(frame, width, height);
    let rendered = render_gt(renderer, frame, &k)?;
    let depth = match &frame.depth {
        Some(p) => {
            let d = read_depth_m(p, frame.camera.depth_scale)?;
            if (d.width, d.height) != (width, height) {
                return Err(Error::malformed(
                    p,
                    format!(
                        "depth image is {}x{} but the camera is {width}x{height}",
                        d.width, d.height
                    ),
                ));
            }
            Some(d.data)
        }
        None => None,
    };
    let real_depth = depth.is_some();
    let scene_depth = depth.as_deref().unwrap_or(&rendered.depth_m);
    let objects = annotate(&k, scene_depth, &rendered.alone, delta_m);
    Ok(FrameAnnotations {
        rendered,
        objects,
        real_depth,
    })
}

/// BOP's full masks and `scene_gt_info` of a frame whose visible masks are given (a
/// dataset's own, e.g. YCB-Video's labels): per object, the silhouette rendered at its GT pose
/// (on the 3x canvas for `bbox_obj` and `px_count_all`), widened by any visible pixel it misses
/// (the two rasterizations differ at edges); the visible counts and box from `visib[gt_id]`;
/// `px_count_valid` from the frame's depth image (0 without one). So the result is consistent
/// with `visib` written as `mask_visib/`.
pub fn complete_annotations(
    renderer: &dyn PoseRenderer,
    frame: &SourceFrame,
    visib: &[Vec<u8>],
    (w, h): (u32, u32),
) -> Result<Vec<(Vec<u8>, GtInfo)>> {
    let ann = annotate_frame(renderer, frame, w, h, DEFAULT_VISIB_DELTA_M)?;
    let depth = match &frame.depth {
        Some(p) => Some(read_depth_raw(p)?),
        None => None,
    };
    let mut out = Vec::with_capacity(frame.gt.len());
    for ((a, alone), v) in ann.objects.iter().zip(&ann.rendered.alone).zip(visib) {
        let mut mask = a.mask.clone();
        let mut extra = 0u64;
        for (m, &l) in mask.iter_mut().zip(v) {
            if l > 0 && *m == 0 {
                *m = 255;
                extra += 1;
            }
        }
        let px_visib = v.iter().filter(|&&x| x > 0).count() as u64;
        let px_all = a.info.px_count_all + extra;
        let px_valid = depth.as_ref().map_or(0, |d| {
            mask.iter()
                .zip(&d.data)
                .filter(|(&m, &z)| m > 0 && z > 0)
                .count() as u64
        });
        let bbox_visib = mask_bbox(v, w);
        let bbox_obj = if px_visib == 0 {
            [-1; 4]
        } else {
            // The rendered silhouette's box, widened by the visible pixels it missed.
            let b = match silhouette_bbox(alone, w, h) {
                [-1, -1, -1, -1] => bbox_visib,
                b => b,
            };
            let (x0, y0) = (b[0].min(bbox_visib[0]), b[1].min(bbox_visib[1]));
            let x1 = (b[0] + b[2]).max(bbox_visib[0] + bbox_visib[2]);
            let y1 = (b[1] + b[3]).max(bbox_visib[1] + bbox_visib[3]);
            [x0, y0, x1 - x0, y1 - y0]
        };
        let visib_fract = if px_all > 0 {
            px_visib as f64 / px_all as f64
        } else {
            0.0
        };
        out.push((
            mask,
            GtInfo {
                bbox_obj,
                bbox_visib,
                px_count_all: px_all,
                px_count_valid: px_valid,
                px_count_visib: px_visib,
                visib_fract,
            },
        ));
    }
    Ok(out)
}

/// [`complete_annotations`], writing each full mask as `scene_dir/mask/{im:06}_{gt:06}.png`;
/// returns the frame's `scene_gt_info` entries.
pub fn write_completed_masks(
    renderer: &dyn PoseRenderer,
    frame: &SourceFrame,
    visib: &[Vec<u8>],
    scene_dir: &Path,
    im_id: u32,
    (w, h): (u32, u32),
) -> Result<Vec<GtInfo>> {
    create_dir_all(&scene_dir.join("mask"))?;
    let mut infos = Vec::with_capacity(frame.gt.len());
    for (gt_id, (mask, info)) in complete_annotations(renderer, frame, visib, (w, h))?
        .into_iter()
        .enumerate()
    {
        let p = scene_dir
            .join("mask")
            .join(format!("{im_id:06}_{gt_id:06}.png"));
        let png = encode_gray8_png(&mask, w, h, PngCompression::Fast, &p)?;
        atomic_write(&p, &png)?;
        infos.push(info);
    }
    Ok(infos)
}

/// Intersection over union of two masks (non-zero = inside); `None` when both are empty.
pub fn mask_iou(a: &[u8], b: &[u8]) -> Option<f64> {
    let (mut inter, mut union) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x > 0, y > 0);
        inter += u64::from(x && y);
        union += u64::from(x || y);
    }
    (union > 0).then(|| inter as f64 / union as f64)
}

/// The `q`-th percentile (0..=100) of `values`, interpolated linearly between the two
/// nearest ranks (numpy's default); `None` for no values.
pub fn percentile(values: &[f64], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let pos = (q / 100.0).clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    Some(v[lo] + (v[hi] - v[lo]) * (pos - lo as f64))
}

/// Agreement colours of [`mask_overlay`]: both masks, only the computed one, only the
/// dataset's own.
pub const OVERLAY_BOTH: [u8; 3] = [40, 200, 60];
pub const OVERLAY_OURS_ONLY: [u8; 3] = [235, 40, 40];
pub const OVERLAY_THEIRS_ONLY: [u8; 3] = [40, 110, 255];

/// The image with two sets of masks over it: where both say "object" in green, only
/// `ours` in red, only `theirs` in blue (half-transparent; the rest dimmed).
pub fn mask_overlay(image: &RgbImage, ours: &[Vec<u8>], theirs: &[Option<Vec<u8>>]) -> Canvas {
    let mut c = Canvas::from_image(image.clone());
    let n = (image.width * image.height) as usize;
    for p in 0..n {
        let mut colour = None;
        for (i, o) in ours.iter().enumerate() {
            let a = o.get(p).is_some_and(|&v| v > 0);
            let b = theirs
                .get(i)
                .and_then(Option::as_ref)
                .is_some_and(|t| t.get(p).is_some_and(|&v| v > 0));
            colour = match (a, b) {
                (true, true) => Some(OVERLAY_BOTH),
                (true, false) => Some(OVERLAY_OURS_ONLY),
                (false, true) => Some(OVERLAY_THEIRS_ONLY),
                (false, false) => colour,
            };
        }
        let px = &mut c.rgb[3 * p..3 * p + 3];
        match colour {
            Some(col) => {
                for (v, k) in px.iter_mut().zip(col) {
                    *v = ((u16::from(*v) + u16::from(k)) / 2) as u8;
                }
            }
            None => px.iter_mut().for_each(|v| *v /= 2),
        }
    }
    c
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate() {
        let v = [4.0, 1.0, 3.0, 2.0];
        assert_eq!(percentile(&v, 50.0), Some(2.5));
        assert!((percentile(&v, 10.0).unwrap() - 1.3).abs() < 1e-12);
        assert_eq!(percentile(&[], 10.0), None);
    }

    #[test]
    fn iou_of_masks() {
        assert_eq!(
            mask_iou(&[255, 255, 0, 0], &[0, 255, 255, 0]),
            Some(1.0 / 3.0)
        );
        assert_eq!(mask_iou(&[0, 0], &[0, 0]), None);
        assert_eq!(mask_iou(&[1, 0], &[9, 0]), Some(1.0));
    }
}
