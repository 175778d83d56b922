//! The images the pages show, made on request from the dataset's files: thumbnails (cached),
//! the depth colour-mapped, the raw depth for the value under the cursor, and the instance
//! masks and their contours as transparent overlays.

use std::io::Cursor;
use std::path::Path;

use image::{ImageFormat, RgbaImage};
use synthgen_curate::preview::PALETTE;
use synthgen_formats::bop::image::read_depth_raw;
use synthgen_formats::source::SourceFrame;

use crate::Error;

/// Thumbnail width in pixels (height keeps the aspect).
pub const THUMB_WIDTH: u32 = 192;

fn decode_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// The file's bytes and its content type (the RGB image as stored: PNG or JPEG).
pub fn file_bytes(path: &Path) -> Result<(Vec<u8>, &'static str), Error> {
    let bytes = std::fs::read(path).map_err(|e| decode_err(path, e))?;
    let kind = match path.extension().and_then(|e| e.to_str()) {
        Some("jpg" | "jpeg") => "image/jpeg",
        _ => "image/png",
    };
    Ok((bytes, kind))
}

/// A JPEG thumbnail of the frame's RGB image.
pub fn thumbnail(frame: &SourceFrame) -> Result<Vec<u8>, Error> {
    let img = image::open(&frame.rgb).map_err(|e| decode_err(&frame.rgb, e))?;
    let h = (img.height() as u64 * THUMB_WIDTH as u64 / img.width().max(1) as u64).max(1) as u32;
    let small = img.thumbnail_exact(THUMB_WIDTH, h).to_rgb8();
    let mut out = Cursor::new(Vec::new());
    small
        .write_to(&mut out, ImageFormat::Jpeg)
        .map_err(|e| decode_err(&frame.rgb, e))?;
    Ok(out.into_inner())
}

fn png(img: &RgbaImage, path: &Path) -> Result<Vec<u8>, Error> {
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, ImageFormat::Png)
        .map_err(|e| decode_err(path, e))?;
    Ok(out.into_inner())
}

/// A perceptual colour map (near blue, far red) from t in [0, 1].
fn turbo(t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let r = 34.61 + t * (1172.33 - t * (10793.56 - t * (33300.12 - t * (38394.49 - t * 14825.05))));
    let g = 23.31 + t * (557.33 + t * (1225.33 - t * (3574.96 - t * (1073.77 + t * 707.56))));
    let b = 27.2 + t * (3211.1 - t * (15327.97 - t * (27814.0 - t * (22569.18 - t * 6838.66))));
    [r, g, b].map(|v| v.clamp(0.0, 255.0) as u8)
}

/// The depth image colour-mapped between its 2nd and 98th percentile; no depth is black.
pub fn depth_colour(frame: &SourceFrame) -> Result<Vec<u8>, Error> {
    let path = frame
        .depth
        .as_ref()
        .ok_or(Error::NotFound("this frame has no depth image"))?;
    let raw = read_depth_raw(path).map_err(|e| decode_err(path, e))?;
    let mut valid: Vec<u16> = raw.data.iter().copied().filter(|&v| v > 0).collect();
    valid.sort_unstable();
    let pick = |q: f64| {
        valid
            .get(((valid.len() as f64 - 1.0) * q) as usize)
            .copied()
            .unwrap_or(0)
    };
    let (lo, hi) = (pick(0.02) as f64, pick(0.98).max(pick(0.02) + 1) as f64);
    let mut img = RgbaImage::new(raw.width, raw.height);
    for (p, &v) in img.pixels_mut().zip(&raw.data) {
        *p = if v == 0 {
            image::Rgba([0, 0, 0, 255])
        } else {
            let [r, g, b] = turbo((v as f64 - lo) / (hi - lo));
            image::Rgba([r, g, b, 255])
        };
    }
    png(&img, path)
}

/// The raw depth: width, height (u32 little-endian), then the uint16 values row by row.
pub fn depth_raw(frame: &SourceFrame) -> Result<Vec<u8>, Error> {
    let path = frame
        .depth
        .as_ref()
        .ok_or(Error::NotFound("this frame has no depth image"))?;
    let raw = read_depth_raw(path).map_err(|e| decode_err(path, e))?;
    let mut out = Vec::with_capacity(8 + raw.data.len() * 2);
    out.extend_from_slice(&raw.width.to_le_bytes());
    out.extend_from_slice(&raw.height.to_le_bytes());
    for v in raw.data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    Ok(out)
}

/// The visible masks as one transparent overlay, each instance in its object's colour; with
/// `contours`, only their outlines (mask pixels with a 4-neighbour outside).
pub fn mask_overlay(frame: &SourceFrame, contours: bool) -> Result<Vec<u8>, Error> {
    let mut img: Option<RgbaImage> = None;
    for (g, m) in frame.masks_visib.iter().enumerate() {
        let Some(m) = m else { continue };
        let plane = m.read().map_err(|e| decode_err(m.path(), e))?;
        let (w, h) = (plane.width as i64, plane.height as i64);
        let img = img.get_or_insert_with(|| RgbaImage::new(plane.width, plane.height));
        if img.width() != plane.width || img.height() != plane.height {
            continue;
        }
        let [r, gg, b] = PALETTE[frame.gt[g].obj_id as usize % PALETTE.len()];
        let at = |x: i64, y: i64| {
            x >= 0 && y >= 0 && x < w && y < h && plane.data[(y * w + x) as usize] > 0
        };
        for y in 0..h {
            for x in 0..w {
                if !at(x, y) {
                    continue;
                }
                let edge = !(at(x - 1, y) && at(x + 1, y) && at(x, y - 1) && at(x, y + 1));
                if contours && !edge {
                    continue;
                }
                let alpha = if contours { 255 } else { 120 };
                img.put_pixel(x as u32, y as u32, image::Rgba([r, gg, b, alpha]));
            }
        }
    }
    let img = img.ok_or(Error::NotFound("this frame has no visible masks"))?;
    png(&img, &frame.rgb)
}
