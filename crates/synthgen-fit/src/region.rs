//! The colour regions on either side of a model's outline: a second cue for
//! [`crate::edge_refine`] beside the image's edges, in the manner of region-based trackers
//! (PWP3D, Prisacariu & Reid 2012; RBOT, Tjaden et al. 2019). At a pose, the pixels inside the
//! model's silhouette and those around it give two colour histograms; each pixel of the region
//! then gets the posterior that its colour is the object's. A contour point costs little where
//! the pixels just inside it look like the object and those just outside like its
//! surroundings. Clutter edges and a blurred outline do not mislead it the way they mislead a
//! chamfer distance: it reads colours on both sides, not the position of a gradient maximum.

use synthgen_core::glam::DVec3;
use synthgen_core::{Intrinsics, Pose};

use crate::raster::{project, Rect, ZBuffer};

/// Levels per colour channel of the histograms.
const LEVELS: usize = 16;
/// Posteriors are kept within this of 0 and 1, so that one pixel costs at most ~3.9.
const CLAMP: f32 = 0.02;
/// Pixels sampled on each side of a contour point, one pixel apart.
const SAMPLES: usize = 4;

/// The colours of an image region (RGB8, row-major over `rect`).
#[derive(Debug, Clone)]
pub struct RegionColours {
    pub rect: Rect,
    rgb: Vec<[u8; 3]>,
}

impl RegionColours {
    /// `rect`'s pixels of a `width × height` RGB8 image.
    pub fn new(rgb: &[u8], width: u32, height: u32, rect: Rect) -> RegionColours {
        let mut out = Vec::with_capacity((rect.w * rect.h).max(0) as usize);
        for y in rect.y0..rect.y0 + rect.h {
            for x in rect.x0..rect.x0 + rect.w {
                let (x, y) = (
                    x.clamp(0, width as i32 - 1) as usize,
                    y.clamp(0, height as i32 - 1) as usize,
                );
                let p = &rgb[(y * width as usize + x) * 3..][..3];
                out.push([p[0], p[1], p[2]]);
            }
        }
        RegionColours { rect, rgb: out }
    }

    /// The colour of image pixel (x, y) (pixel centres at whole coordinates); None outside
    /// the region.
    pub(crate) fn at(&self, x: f64, y: f64) -> Option<[u8; 3]> {
        self.rect.index_of(x, y).map(|at| self.rgb[at])
    }
}

fn bin(c: [u8; 3]) -> usize {
    let q = |v: u8| usize::from(v) * LEVELS / 256;
    (q(c[0]) * LEVELS + q(c[1])) * LEVELS + q(c[2])
}

/// Per pixel of a region, the posterior that its colour is the object's.
#[derive(Debug, Clone)]
pub struct RegionField {
    rect: Rect,
    posterior: Vec<f32>,
}

impl RegionField {
    /// The histograms of the pixels inside the model's silhouette at `pose` and of the
    /// region's others (each normalized, so the two count alike whatever their areas), and
    /// each pixel's posterior from them. None when either side has fewer than 20 pixels.
    pub fn new(
        colours: &RegionColours,
        triangles: &[[DVec3; 3]],
        pose: &Pose,
        k: &Intrinsics,
        raster_px: u32,
    ) -> Option<RegionField> {
        let z = ZBuffer::new(triangles, pose, k, colours.rect, raster_px);
        RegionField::of_silhouette(colours, &z)
    }

    /// [`RegionField::new`] with the model already rasterized over `colours.rect`.
    pub(crate) fn of_silhouette(colours: &RegionColours, z: &ZBuffer) -> Option<RegionField> {
        let rect = colours.rect;
        let (w, h) = (rect.w as usize, rect.h as usize);
        let inside: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = (rect.x0 + (i % w) as i32, rect.y0 + (i / w) as i32);
                z.covers(f64::from(x), f64::from(y))
            })
            .collect();
        let mut fg = vec![0.0f32; LEVELS * LEVELS * LEVELS];
        let mut bg = fg.clone();
        let (mut nf, mut nb) = (0usize, 0usize);
        for (c, &i) in colours.rgb.iter().zip(&inside) {
            if i {
                fg[bin(*c)] += 1.0;
                nf += 1;
            } else {
                bg[bin(*c)] += 1.0;
                nb += 1;
            }
        }
        if nf < 20 || nb < 20 {
            return None;
        }
        let posterior = colours
            .rgb
            .iter()
            .map(|c| {
                let b = bin(*c);
                let (f, g) = (fg[b] / nf as f32, bg[b] / nb as f32);
                if f + g <= 0.0 {
                    0.5
                } else {
                    (f / (f + g)).clamp(CLAMP, 1.0 - CLAMP)
                }
            })
            .collect();
        Some(RegionField { rect, posterior })
    }

    /// The posterior at image pixel (x, y) (pixel centres at whole coordinates); 0.5 outside
    /// the region.
    fn at(&self, x: f64, y: f64) -> f32 {
        self.rect
            .index_of(x, y)
            .map_or(0.5, |at| self.posterior[at])
    }

    /// The mean cost of `points` (outline points of a contour: each with a second point one
    /// pixel along its tangent, the object on the tangent's right, as
    /// [`crate::edge_refine::contour`] extracts them) at `pose`: per point, the negative log
    /// posterior of "object" at [`SAMPLES`] pixels inwards along its normal and of "not
    /// object" at as many outwards, averaged. None when no point projects.
    pub fn cost(&self, points: &[[DVec3; 2]], pose: &Pose, k: &Intrinsics) -> Option<f64> {
        let (mut sum, mut n) = (0.0f64, 0usize);
        for [p, q] in points {
            let (Some(a), Some(b)) = (
                project(k, pose.rotation * *p + pose.translation_m),
                project(k, pose.rotation * *q + pose.translation_m),
            ) else {
                continue;
            };
            let t = b - a;
            let len = t.length();
            if len < 1e-9 {
                continue;
            }
            // The contour's inward normal: its tangent turned by a right angle.
            let inward = synthgen_core::glam::DVec2::new(t.y, -t.x) / len;
            let mut c = 0.0f64;
            for s in 1..=SAMPLES {
                let d = s as f64 - 0.5;
                let i = a + inward * d;
                let o = a - inward * d;
                c -= f64::from(self.at(i.x, i.y)).ln();
                c -= f64::from(1.0 - self.at(o.x, o.y)).ln();
            }
            sum += c / (2 * SAMPLES) as f64;
            n += 1;
        }
        (n > 0).then(|| sum / n as f64)
    }
}
