//! The small rasterizer the RGB refinement needs: a model's triangles at a pose over an image
//! region (a z-buffer with the triangle and barycentric weights per pixel), shared by the
//! contour extraction of [`crate::edge_refine`] and the colour comparison of
//! [`crate::appearance`], and the Sobel operator both read images with.

use synthgen_core::glam::{DVec2, DVec3};
use synthgen_core::{Intrinsics, Pose};

/// A pixel rectangle of the image: `x0..x0 + w`, `y0..y0 + h`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    pub x0: i32,
    pub y0: i32,
    pub w: i32,
    pub h: i32,
}

impl Rect {
    /// The square of side `side` centred on (cx, cy), clipped to a `width × height` image;
    /// None when nothing of it is inside.
    pub fn square_in(cx: f64, cy: f64, side: f64, width: u32, height: u32) -> Option<Rect> {
        let x0 = (cx - 0.5 * side).floor().max(0.0) as i32;
        let y0 = (cy - 0.5 * side).floor().max(0.0) as i32;
        let x1 = ((cx + 0.5 * side).ceil() as i32).min(width as i32);
        let y1 = ((cy + 0.5 * side).ceil() as i32).min(height as i32);
        (x1 - x0 >= 8 && y1 - y0 >= 8).then_some(Rect {
            x0,
            y0,
            w: x1 - x0,
            h: y1 - y0,
        })
    }

    /// The row-major index within the rectangle of the image pixel that (x, y) falls in
    /// (pixel centres at whole coordinates: pixel i spans [i - 0.5, i + 0.5)); None outside.
    pub(crate) fn index_of(&self, x: f64, y: f64) -> Option<usize> {
        let (x, y) = ((x + 0.5).floor(), (y + 0.5).floor());
        self.contains(x, y).then(|| {
            (y as i32 - self.y0) as usize * self.w as usize + (x as i32 - self.x0) as usize
        })
    }

    pub(crate) fn contains(&self, x: f64, y: f64) -> bool {
        x >= f64::from(self.x0)
            && y >= f64::from(self.y0)
            && x < f64::from(self.x0 + self.w)
            && y < f64::from(self.y0 + self.h)
    }
}

/// The object-frame point seen at image point `p` (pixels) at camera depth `depth` (metres)
/// with the object at `pose`: [`project`]'s inverse, back into the object frame.
pub(crate) fn to_object(k: &Intrinsics, pose: &Pose, p: DVec2, depth: f64) -> DVec3 {
    let cam = DVec3::new(
        (p.x - k.cx) * depth / k.fx,
        (p.y - k.cy) * depth / k.fy,
        depth,
    );
    pose.rotation.transpose() * (cam - pose.translation_m)
}

/// The projection of camera-frame point `p` (pixels); None behind the camera.
pub(crate) fn project(k: &Intrinsics, p: DVec3) -> Option<DVec2> {
    (p.z > 1e-6).then(|| DVec2::new(k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy))
}

/// `triangles` (object frame, metres) at `pose` rasterized over `rect`, at most `raster_px`
/// across (larger regions scaled down): per raster pixel the nearest surface's depth
/// (infinite where none) and which triangle it is with its first two barycentric weights.
pub(crate) struct ZBuffer {
    pub w: usize,
    pub h: usize,
    scale: f64,
    x0: f64,
    y0: f64,
    pub depth: Vec<f32>,
    pub hit: Vec<(u32, [f32; 2])>,
}

impl ZBuffer {
    pub(crate) fn new(
        triangles: &[[DVec3; 3]],
        pose: &Pose,
        k: &Intrinsics,
        rect: Rect,
        raster_px: u32,
    ) -> ZBuffer {
        let scale = (f64::from(raster_px) / f64::from(rect.w.max(rect.h))).min(1.0);
        let w = ((f64::from(rect.w) * scale).round() as usize).max(2);
        let h = ((f64::from(rect.h) * scale).round() as usize).max(2);
        let mut z = ZBuffer {
            w,
            h,
            scale,
            x0: f64::from(rect.x0),
            y0: f64::from(rect.y0),
            depth: vec![f32::INFINITY; w * h],
            hit: vec![(0, [0.0; 2]); w * h],
        };
        for (ti, t) in triangles.iter().enumerate() {
            let c = t.map(|v| pose.rotation * v + pose.translation_m);
            if c.iter().any(|p| p.z < 1e-3) {
                continue;
            }
            let Some(p) = c
                .iter()
                .map(|&p| project(k, p).map(|p| z.to_raster(p)))
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            let area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
            if area.abs() < 1e-12 {
                continue;
            }
            let min = p[0].min(p[1]).min(p[2]);
            let max = p[0].max(p[1]).max(p[2]);
            let i0 = (min.x - 0.5).ceil().max(0.0) as usize;
            let j0 = (min.y - 0.5).ceil().max(0.0) as usize;
            let i1 = ((max.x - 0.5).floor() as i64).min(w as i64 - 1);
            let j1 = ((max.y - 0.5).floor() as i64).min(h as i64 - 1);
            if i1 < i0 as i64 || j1 < j0 as i64 {
                continue;
            }
            let inv_z = [1.0 / c[0].z, 1.0 / c[1].z, 1.0 / c[2].z];
            for j in j0..=j1 as usize {
                for i in i0..=i1 as usize {
                    let q = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                    let b0 = (p[2] - p[1]).perp_dot(q - p[1]) / area;
                    let b1 = (p[0] - p[2]).perp_dot(q - p[2]) / area;
                    let b2 = 1.0 - b0 - b1;
                    if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                        continue;
                    }
                    let depth = (1.0 / (b0 * inv_z[0] + b1 * inv_z[1] + b2 * inv_z[2])) as f32;
                    let d = &mut z.depth[j * w + i];
                    if depth < *d {
                        *d = depth;
                        // Perspective-correct weights of the first two corners.
                        let s = f64::from(depth);
                        z.hit[j * w + i] = (
                            ti as u32,
                            [(b0 * inv_z[0] * s) as f32, (b1 * inv_z[1] * s) as f32],
                        );
                    }
                }
            }
        }
        z
    }

    // Image pixel centres are at whole coordinates (OpenCV's convention, BOP's); raster
    // pixel (i, j) spans [i, i + 1) in raster coordinates, its centre at i + 0.5.
    fn to_raster(&self, p: DVec2) -> DVec2 {
        DVec2::new(
            (p.x + 0.5 - self.x0) * self.scale,
            (p.y + 0.5 - self.y0) * self.scale,
        )
    }

    /// Whether the surface covers the raster pixel that image pixel (x, y)'s centre falls in.
    pub(crate) fn covers(&self, x: f64, y: f64) -> bool {
        let r = self.to_raster(DVec2::new(x, y));
        if r.x < 0.0 || r.y < 0.0 {
            return false;
        }
        let (i, j) = (r.x as usize, r.y as usize);
        i < self.w && j < self.h && self.depth[j * self.w + i].is_finite()
    }

    pub(crate) fn to_image(&self, r: DVec2) -> DVec2 {
        DVec2::new(
            self.x0 + r.x / self.scale - 0.5,
            self.y0 + r.y / self.scale - 0.5,
        )
    }
}

/// The Sobel gradient / 8 (grey levels per pixel) at a pixel of `g`, read by offsets.
pub(crate) fn sobel(g: impl Fn(isize, isize) -> f32) -> (f32, f32) {
    let gx = (g(1, -1) + 2.0 * g(1, 0) + g(1, 1) - g(-1, -1) - 2.0 * g(-1, 0) - g(-1, 1)) / 8.0;
    let gy = (g(-1, 1) + 2.0 * g(0, 1) + g(1, 1) - g(-1, -1) - 2.0 * g(0, -1) - g(1, -1)) / 8.0;
    (gx, gy)
}
