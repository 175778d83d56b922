//! Renderer output and the BOP ground-truth quantities derived from it (`scene_gt_info`,
//! `mask`, `mask_visib`), computed the way bop_toolkit's `calc_gt_info` / `calc_gt_masks` do.

use serde::{Deserialize, Serialize};

use crate::Intrinsics;

/// Depth of one object rendered alone, on a window of a canvas three times the image size
/// (the image sits in its middle), as bop_toolkit renders it for `bbox_obj` and
/// `px_count_all`. Coordinates are image pixels: `x0`, `y0` may be negative.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AloneDepth {
    pub x0: i32,
    pub y0: i32,
    pub width: u32,
    pub height: u32,
    /// Depth along the optical axis in metres, row-major, `0.0` where the object is not.
    pub depth_m: Vec<f32>,
}

impl AloneDepth {
    /// Depth at image pixel (x, y), 0 outside the window.
    pub fn at(&self, x: i32, y: i32) -> f32 {
        let (lx, ly) = (x - self.x0, y - self.y0);
        if lx < 0 || ly < 0 || lx >= self.width as i32 || ly >= self.height as i32 {
            return 0.0;
        }
        self.depth_m[ly as usize * self.width as usize + lx as usize]
    }
}

/// What any renderer produces for one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderedFrame {
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` sRGB bytes, row-major.
    pub rgb: Vec<u8>,
    /// Depth along the optical axis (z) in metres; 0 where nothing was hit.
    pub depth_m: Vec<f32>,
    /// Per pixel: 0 for background and ground, `i + 1` for `FrameScene::objects[i]`.
    pub instance: Vec<u16>,
    /// Per object, in the order of `FrameScene::objects`.
    pub alone: Vec<AloneDepth>,
}

/// BOP `scene_gt_info` entry. Boxes are `[x, y, w, h]` with `w = x_max - x_min` (bop_toolkit's
/// `calc_2d_bbox`, no +1); `[-1, -1, -1, -1]` when empty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GtInfo {
    pub bbox_obj: [i32; 4],
    pub bbox_visib: [i32; 4],
    pub px_count_all: u64,
    pub px_count_valid: u64,
    pub px_count_visib: u64,
    pub visib_fract: f64,
}

/// Masks (0 or 255 per pixel, image size) and gt info for one object.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectAnnotation {
    /// Full silhouette inside the image, as if the object were alone (`mask/`).
    pub mask: Vec<u8>,
    /// Visible part (`mask_visib/`).
    pub mask_visib: Vec<u8>,
    pub info: GtInfo,
}

/// bop_toolkit's default visibility tolerance (`delta`, 15 mm).
pub const DEFAULT_VISIB_DELTA_M: f32 = 0.015;

#[derive(Default)]
struct BboxAcc {
    min: [i32; 2],
    max: [i32; 2],
    any: bool,
}

impl BboxAcc {
    fn add(&mut self, x: i32, y: i32) {
        if self.any {
            self.min = [self.min[0].min(x), self.min[1].min(y)];
            self.max = [self.max[0].max(x), self.max[1].max(y)];
        } else {
            *self = BboxAcc {
                min: [x, y],
                max: [x, y],
                any: true,
            };
        }
    }
    fn bbox(&self) -> [i32; 4] {
        if self.any {
            [
                self.min[0],
                self.min[1],
                self.max[0] - self.min[0],
                self.max[1] - self.min[1],
            ]
        } else {
            [-1, -1, -1, -1]
        }
    }
}

/// BOP's `[x, y, w, h]` of the non-zero pixels of a row-major mask `width` pixels wide;
/// `[-1, -1, -1, -1]` when empty.
pub fn mask_bbox(mask: &[u8], width: u32) -> [i32; 4] {
    let mut acc = BboxAcc::default();
    for (i, _) in mask.iter().enumerate().filter(|(_, &v)| v > 0) {
        acc.add((i % width as usize) as i32, (i / width as usize) as i32);
    }
    acc.bbox()
}

/// BOP's `[x, y, w, h]` of an object's whole silhouette (on the 3x canvas, so it may start
/// at negative coordinates); `[-1, -1, -1, -1]` when it covers no pixel.
pub fn silhouette_bbox(a: &AloneDepth, width: u32, height: u32) -> [i32; 4] {
    let (w, h) = (width as i32, height as i32);
    let mut acc = BboxAcc::default();
    for ly in 0..a.height as i32 {
        let y = a.y0 + ly;
        let row = &a.depth_m[(ly as usize) * a.width as usize..][..a.width as usize];
        for (lx, &d) in row.iter().enumerate() {
            let x = a.x0 + lx as i32;
            if d > 0.0 && x >= -w && y >= -h && x < 2 * w && y < 2 * h {
                acc.add(x, y);
            }
        }
    }
    acc.bbox()
}

/// bop_toolkit's "bop19" visibility of one silhouette pixel (x, y) whose object depth is
/// `object_m`, against the scene depth `scene_m` (0 = no reading, which counts as visible):
/// the object's surface is at most `delta_m` behind the scene's *along the pixel's ray*
/// (bop_toolkit compares distance images, `depth_im_to_dist_im_fast`: depth ×
/// √(((x − cx)/fx)² + ((y − cy)/fy)² + 1)).
#[inline]
pub fn visible_bop19(
    k: &Intrinsics,
    x: i32,
    y: i32,
    object_m: f32,
    scene_m: f32,
    delta_m: f32,
) -> bool {
    let behind = object_m - scene_m;
    if scene_m == 0.0 || behind <= 0.0 {
        return true;
    }
    let u = (f64::from(x) - k.cx) / k.fx;
    let v = (f64::from(y) - k.cy) / k.fy;
    behind * ((u * u + v * v + 1.0).sqrt() as f32) <= delta_m
}

/// Computes masks and gt info for every object of a frame, as bop_toolkit's `calc_gt_info`
/// and `calc_gt_masks` do.
///
/// `scene_depth_m` is the depth the visibility test ([`visible_bop19`]) compares against: the
/// rendered scene depth, or a sensor's depth with holes.
/// `px_count_valid` counts silhouette pixels with scene depth > 0; `bbox_obj` is
/// `[-1, -1, -1, -1]` when no pixel is visible, as bop_toolkit leaves it.
pub fn annotate(
    k: &Intrinsics,
    scene_depth_m: &[f32],
    alone: &[AloneDepth],
    delta_m: f32,
) -> Vec<ObjectAnnotation> {
    let (width, height) = (k.width, k.height);
    let (w, h) = (width as i32, height as i32);
    let n = (width * height) as usize;
    alone
        .iter()
        .map(|a| {
            let mut mask = vec![0u8; n];
            let mut mask_visib = vec![0u8; n];
            let mut all = BboxAcc::default();
            let mut visib = BboxAcc::default();
            let (mut px_all, mut px_valid, mut px_visib) = (0u64, 0u64, 0u64);
            for ly in 0..a.height as i32 {
                let y = a.y0 + ly;
                let row = &a.depth_m[(ly as usize) * a.width as usize..][..a.width as usize];
                for (lx, &d) in row.iter().enumerate() {
                    if d <= 0.0 {
                        continue;
                    }
                    let x = a.x0 + lx as i32;
                    // The canvas is three times the image, centred on it.
                    if x < -w || y < -h || x >= 2 * w || y >= 2 * h {
                        continue;
                    }
                    px_all += 1;
                    all.add(x, y);
                    if x < 0 || y < 0 || x >= w || y >= h {
                        continue;
                    }
                    let i = y as usize * width as usize + x as usize;
                    mask[i] = 255;
                    let ds = scene_depth_m[i];
                    if ds > 0.0 {
                        px_valid += 1;
                    }
                    if visible_bop19(k, x, y, d, ds, delta_m) {
                        mask_visib[i] = 255;
                        px_visib += 1;
                        visib.add(x, y);
                    }
                }
            }
            let visib_fract = if px_all > 0 {
                px_visib as f64 / px_all as f64
            } else {
                0.0
            };
            ObjectAnnotation {
                mask,
                mask_visib,
                info: GtInfo {
                    bbox_obj: if px_visib > 0 { all.bbox() } else { [-1; 4] },
                    bbox_visib: visib.bbox(),
                    px_count_all: px_all,
                    px_count_valid: px_valid,
                    px_count_visib: px_visib,
                    visib_fract,
                },
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k(width: u32, height: u32) -> Intrinsics {
        Intrinsics {
            width,
            height,
            fx: 500.0,
            fy: 500.0,
            cx: f64::from(width) / 2.0,
            cy: f64::from(height) / 2.0,
        }
    }

    /// bop_toolkit compares distances along the ray, not depths: 14 mm behind in depth is
    /// visible on the optical axis and hidden far off it, where the ray is 1.2x longer.
    #[test]
    fn visibility_compares_distances_along_the_ray() {
        let k = Intrinsics {
            width: 2,
            height: 1,
            fx: 1.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
        };
        // Pixel (0, 0) is on the axis; pixel (1, 0) at 45° (ray factor √2).
        let a = AloneDepth {
            x0: 0,
            y0: 0,
            width: 2,
            height: 1,
            depth_m: vec![1.014, 1.014],
        };
        let ann = annotate(&k, &[1.0, 1.0], &[a], DEFAULT_VISIB_DELTA_M);
        assert_eq!(ann[0].mask_visib, [255, 0]);
        // Nothing visible: no bbox_obj either, as bop_toolkit.
        let hidden = AloneDepth {
            x0: 0,
            y0: 0,
            width: 1,
            height: 1,
            depth_m: vec![2.0],
        };
        let ann = annotate(&k, &[1.0, 1.0], &[hidden], DEFAULT_VISIB_DELTA_M);
        assert_eq!(ann[0].info.px_count_all, 1);
        assert_eq!(ann[0].info.bbox_obj, [-1; 4]);
    }

    fn square(x0: i32, y0: i32, side: u32, depth: f32) -> AloneDepth {
        AloneDepth {
            x0,
            y0,
            width: side,
            height: side,
            depth_m: vec![depth; (side * side) as usize],
        }
    }

    #[test]
    fn occlusion_counts_and_boxes() {
        // 20x10 image; a far square 6x6 at (2,2), a near square 4x4 at (4,4) covering a 4x4
        // corner of it.
        let (w, h) = (20u32, 10u32);
        let far = square(2, 2, 6, 1.0);
        let near = square(4, 4, 4, 0.5);
        let mut depth = vec![0f32; (w * h) as usize];
        for a in [&far, &near] {
            for y in 0..h as i32 {
                for x in 0..w as i32 {
                    let d = a.at(x, y);
                    let s = &mut depth[(y as u32 * w + x as u32) as usize];
                    if d > 0.0 && (*s == 0.0 || d < *s) {
                        *s = d;
                    }
                }
            }
        }
        let ann = annotate(&k(w, h), &depth, &[far, near], DEFAULT_VISIB_DELTA_M);
        let f = &ann[0].info;
        assert_eq!(f.px_count_all, 36);
        assert_eq!(f.px_count_visib, 36 - 16);
        assert_eq!(f.px_count_valid, 36);
        assert!((f.visib_fract - 20.0 / 36.0).abs() < 1e-12);
        assert_eq!(f.bbox_obj, [2, 2, 5, 5]);
        assert_eq!(f.bbox_visib, [2, 2, 5, 5]);
        assert_eq!(ann[0].mask.iter().filter(|&&v| v == 255).count(), 36);
        assert_eq!(ann[0].mask_visib.iter().filter(|&&v| v == 255).count(), 20);
        let n = &ann[1].info;
        assert_eq!((n.px_count_all, n.px_count_visib), (16, 16));
        assert_eq!(n.bbox_visib, [4, 4, 3, 3]);
    }

    #[test]
    fn truncated_object_keeps_whole_silhouette() {
        let (w, h) = (10u32, 10u32);
        let a = square(-3, 7, 5, 1.0);
        let depth = vec![0f32; 100];
        let ann = annotate(&k(w, h), &depth, &[a], DEFAULT_VISIB_DELTA_M);
        let i = &ann[0].info;
        assert_eq!(i.px_count_all, 25);
        assert_eq!(i.bbox_obj, [-3, 7, 4, 4]);
        // In-image part: x 0..2, y 7..10 -> 2 x 3 = 6 pixels, visible because depth missing.
        assert_eq!(i.px_count_visib, 6);
        assert_eq!(i.px_count_valid, 0);
        assert_eq!(i.bbox_visib, [0, 7, 1, 2]);
    }

    #[test]
    fn invisible_object_has_minus_one_boxes() {
        let ann = annotate(&k(4, 4), &[0.0; 16], &[AloneDepth::default()], 0.015);
        assert_eq!(ann[0].info.bbox_obj, [-1; 4]);
        assert_eq!(ann[0].info.bbox_visib, [-1; 4]);
        assert_eq!(ann[0].info.visib_fract, 0.0);
    }
}
