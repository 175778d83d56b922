//! Where an instance lies in its image, and the pixels kept around it: the square box
//! regions the RGB models crop from (the colour, and the dense model's object-coordinate
//! targets over the same square), and the bilinear resampling that cuts them.

use crate::models::rgb::{Pinhole, SquareBox};

/// The nominal crop's side over the box's longer side (some context around the object).
pub const CONTEXT: f64 = 1.25;
/// The stored region's side over the box's longer side: room for every jittered crop.
pub const STORED_CONTEXT: f64 = 2.0;
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
pub(crate) fn edge_rect(b: &SquareBox) -> [f64; 4] {
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

/// Bilinear resize of the `bbox` region (x, y, w, h) of an RGB image to `size × size`.
pub fn crop_resize(rgb: &[u8], width: u32, height: u32, bbox: [f64; 4], size: u32) -> Vec<u8> {
    let [x0, y0, w, h] = bbox;
    let mut out = Vec::with_capacity((size * size * 3) as usize);
    let px = |x: i64, y: i64, c: usize| -> f32 {
        let x = x.clamp(0, i64::from(width) - 1) as usize;
        let y = y.clamp(0, i64::from(height) - 1) as usize;
        f32::from(rgb[(y * width as usize + x) * 3 + c])
    };
    for j in 0..size {
        for i in 0..size {
            let sx = x0 + (f64::from(i) + 0.5) * w / f64::from(size) - 0.5;
            let sy = y0 + (f64::from(j) + 0.5) * h / f64::from(size) - 0.5;
            let (fx, fy) = (sx.floor(), sy.floor());
            let (ax, ay) = ((sx - fx) as f32, (sy - fy) as f32);
            let (xi, yi) = (fx as i64, fy as i64);
            for c in 0..3 {
                let top = px(xi, yi, c) * (1.0 - ax) + px(xi + 1, yi, c) * ax;
                let bot = px(xi, yi + 1, c) * (1.0 - ax) + px(xi + 1, yi + 1, c) * ax;
                out.push((top * (1.0 - ay) + bot * ay).round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    out
}
