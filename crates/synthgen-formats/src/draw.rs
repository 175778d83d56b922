//! A small RGB canvas for contact sheets and plots: lines, rectangles, a 3x5 bitmap font
//! for digits, box-filter downscaling and PNG output. No system fonts needed.

use std::path::Path;

use crate::bop::image::{encode_rgb_png, PngCompression, RgbImage};
use crate::error::Result;
use crate::io::atomic_write;

pub type Rgb = [u8; 3];

#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    /// Row-major, 3 bytes per pixel.
    pub rgb: Vec<u8>,
}

/// 3x5 glyphs, one row per u8 (bit 2 = left column). Letters are upper case (lower case
/// is drawn the same).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c.to_ascii_uppercase() {
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [3, 4, 4, 4, 3],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [3, 4, 5, 5, 3],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 2],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [2, 5, 5, 5, 2],
        'P' => [6, 5, 6, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [3, 4, 2, 1, 6],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        ':' => [0, 2, 0, 2, 0],
        '%' => [5, 1, 2, 4, 5],
        '/' => [1, 1, 2, 4, 4],
        '(' => [1, 2, 2, 2, 1],
        ')' => [4, 2, 2, 2, 4],
        '=' => [0, 7, 0, 7, 0],
        '+' => [0, 2, 7, 2, 0],
        ',' => [0, 0, 0, 2, 4],
        '<' => [1, 2, 4, 2, 1],
        '>' => [4, 2, 1, 2, 4],
        '_' => [0, 0, 0, 0, 7],
        '°' => [2, 5, 2, 0, 0],
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 3, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 2, 2],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        ' ' => [0, 0, 0, 0, 0],
        _ => return None,
    })
}

impl Canvas {
    pub fn new(width: u32, height: u32, fill: Rgb) -> Canvas {
        Canvas {
            width,
            height,
            rgb: fill.repeat((width * height) as usize),
        }
    }

    pub fn from_image(img: RgbImage) -> Canvas {
        Canvas {
            width: img.width,
            height: img.height,
            rgb: img.rgb,
        }
    }

    pub fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        self.rgb[i..i + 3].copy_from_slice(&c);
    }

    pub fn fill_rect(&mut self, x: i64, y: i64, w: i64, h: i64, c: Rgb) {
        for yy in y.max(0)..(y + h).min(self.height as i64) {
            for xx in x.max(0)..(x + w).min(self.width as i64) {
                self.set(xx, yy, c);
            }
        }
    }

    /// A line `thickness` pixels wide; endpoints far outside are clipped to a margin first.
    pub fn line(&mut self, a: (f64, f64), b: (f64, f64), c: Rgb, thickness: i64) {
        let Some((a, b)) = clip(a, b, self.width as f64, self.height as f64) else {
            return;
        };
        let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as i64;
        let r = thickness / 2;
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let x = (a.0 + (b.0 - a.0) * t).round() as i64;
            let y = (a.1 + (b.1 - a.1) * t).round() as i64;
            for dy in -r..thickness - r {
                for dx in -r..thickness - r {
                    self.set(x + dx, y + dy, c);
                }
            }
        }
    }

    /// Text (digits, letters, common signs) at `scale` pixels per font pixel, on a dark box.
    pub fn text(&mut self, x: i64, y: i64, s: &str, scale: i64, c: Rgb) {
        let n = s.chars().count() as i64;
        self.fill_rect(
            x - scale,
            y - scale,
            n * 4 * scale + scale,
            7 * scale,
            [0, 0, 0],
        );
        self.label(x, y, s, scale, c);
    }

    /// Text like [`text`](Self::text) but without the box behind it.
    pub fn label(&mut self, x: i64, y: i64, s: &str, scale: i64, c: Rgb) {
        for (k, ch) in s.chars().enumerate() {
            let Some(g) = glyph(ch) else { continue };
            for (row, bits) in g.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        let px = x + (k as i64 * 4 + col) * scale;
                        let py = y + row as i64 * scale;
                        self.fill_rect(px, py, scale, scale, c);
                    }
                }
            }
        }
    }

    /// Box-filter (area average) resize to `width` x `height`.
    pub fn resized(&self, width: u32, height: u32) -> Canvas {
        let mut out = Canvas::new(width.max(1), height.max(1), [0, 0, 0]);
        let sx = self.width as f64 / out.width as f64;
        let sy = self.height as f64 / out.height as f64;
        for y in 0..out.height {
            let y0 = (y as f64 * sy) as u32;
            let y1 = (((y + 1) as f64 * sy).ceil() as u32).clamp(y0 + 1, self.height);
            for x in 0..out.width {
                let x0 = (x as f64 * sx) as u32;
                let x1 = (((x + 1) as f64 * sx).ceil() as u32).clamp(x0 + 1, self.width);
                let mut acc = [0u32; 3];
                for yy in y0..y1 {
                    for xx in x0..x1 {
                        let i = (yy as usize * self.width as usize + xx as usize) * 3;
                        for (a, v) in acc.iter_mut().zip(&self.rgb[i..i + 3]) {
                            *a += u32::from(*v);
                        }
                    }
                }
                let n = (y1 - y0) * (x1 - x0);
                let o = (y as usize * out.width as usize + x as usize) * 3;
                for (dst, a) in out.rgb[o..o + 3].iter_mut().zip(acc) {
                    *dst = (a / n.max(1)) as u8;
                }
            }
        }
        out
    }

    /// Copies `src` with its top-left corner at (x, y).
    pub fn blit(&mut self, src: &Canvas, x: u32, y: u32) {
        for row in 0..src.height.min(self.height.saturating_sub(y)) {
            let w = src.width.min(self.width.saturating_sub(x)) as usize * 3;
            let s = row as usize * src.width as usize * 3;
            let d = ((y + row) as usize * self.width as usize + x as usize) * 3;
            self.rgb[d..d + w].copy_from_slice(&src.rgb[s..s + w]);
        }
    }

    /// Writes the canvas as a PNG, creating the missing folders above it (as `sensor fit
    /// --out` and every other output of synthgen does).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            crate::io::create_dir_all(dir)?;
        }
        let bytes = encode_rgb_png(
            &self.rgb,
            self.width,
            self.height,
            PngCompression::High,
            path,
        )?;
        atomic_write(path, &bytes)
    }
}

/// Clips segment ab to the rectangle [-m, w+m] x [-m, h+m] (Liang–Barsky), so lines to
/// points projected far away stay cheap.
fn clip(a: (f64, f64), b: (f64, f64), w: f64, h: f64) -> Option<((f64, f64), (f64, f64))> {
    if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
        return None;
    }
    let m = 4.0;
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 + m),
        (dx, w + m - a.0),
        (-dy, a.1 + m),
        (dy, h + m - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some((
        (a.0 + dx * t0, a.1 + dy * t0),
        (a.0 + dx * t1, a.1 + dy * t1),
    ))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn line_and_text_draw_pixels() {
        let mut c = Canvas::new(20, 10, [0, 0, 0]);
        c.line((0.0, 0.0), (19.0, 9.0), [255, 0, 0], 1);
        assert_eq!(&c.rgb[0..3], &[255, 0, 0]);
        let last = (9 * 20 + 19) * 3;
        assert_eq!(&c.rgb[last..last + 3], &[255, 0, 0]);
        c.line((-1e9, 5.0), (1e9, 5.0), [0, 255, 0], 1);
        assert_eq!(
            &c.rgb[(5 * 20 + 10) * 3..(5 * 20 + 10) * 3 + 3],
            &[0, 255, 0]
        );
        c.text(2, 2, "1", 1, [9, 9, 9]);
        assert_eq!(&c.rgb[(2 * 20 + 3) * 3..(2 * 20 + 3) * 3 + 3], &[9, 9, 9]);
    }

    #[test]
    fn resize_averages() {
        let mut c = Canvas::new(2, 2, [0, 0, 0]);
        c.set(0, 0, [200, 100, 40]);
        let r = c.resized(1, 1);
        assert_eq!(r.rgb, vec![50, 25, 10]);
    }
}
