//! Encoding and decoding the images of a BOP dataset: RGB (PNG or JPEG), uint16 depth PNG,
//! 8-bit 0/255 mask PNG.

use std::io::Cursor;
use std::path::Path;

use crate::error::{Error, Result};
use crate::io;

/// PNG compression. Measured with `examples/png_timing.rs` (release, one core, 640x480,
/// one frame = RGB + uint16 depth + 10 masks): `Fastest` ~5 ms, `Fast` ~7 ms, `Balanced`
/// 180–280 ms, `High` 480–740 ms. `Fast` is the default: depth PNGs a third smaller than
/// `Fastest` for ~1.5 ms more; zlib levels are far too slow for 60 frames/s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PngCompression {
    /// fdeflate's ultra-fast mode with the `Up` filter: fastest, larger files.
    Fastest,
    /// fdeflate's ultra-fast mode with adaptive filtering.
    #[default]
    Fast,
    /// zlib level 6 with adaptive filtering (what most PNG writers do).
    Balanced,
    /// zlib level 9.
    High,
}

impl PngCompression {
    fn to_png(self) -> png::Compression {
        match self {
            PngCompression::Fastest => png::Compression::Fastest,
            PngCompression::Fast => png::Compression::Fast,
            PngCompression::Balanced => png::Compression::Balanced,
            PngCompression::High => png::Compression::High,
        }
    }
}

/// Format of the `rgb/` images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RgbFormat {
    #[default]
    Png,
    /// JPEG with quality 1..=100 (BlenderProc's PBR datasets use 95). Smaller files but
    /// slower than PNG `Fast` here: ~10–25 ms per 640x480 image.
    Jpg { quality: u8 },
}

impl RgbFormat {
    pub fn extension(&self) -> &'static str {
        match self {
            RgbFormat::Png => "png",
            RgbFormat::Jpg { .. } => "jpg",
        }
    }
}

/// A single-channel image, row-major.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Plane<T> {
    pub width: u32,
    pub height: u32,
    pub data: Vec<T>,
}

/// An 8-bit RGB image, row-major, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

fn encode_png(
    bytes: &[u8],
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    compression: PngCompression,
) -> std::result::Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::with_capacity(bytes.len() / 4 + 1024);
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(color);
    enc.set_depth(depth);
    enc.set_compression(compression.to_png());
    let mut writer = enc.write_header()?;
    writer.write_image_data(bytes)?;
    writer.finish()?;
    Ok(out)
}

/// PNG of an RGB8 image; `path` only names the file in errors.
pub fn encode_rgb_png(
    rgb: &[u8],
    width: u32,
    height: u32,
    compression: PngCompression,
    path: &Path,
) -> Result<Vec<u8>> {
    encode_png(
        rgb,
        width,
        height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        compression,
    )
    .map_err(|e| encode_err(e, path))
}

/// PNG of an 8-bit grayscale image (masks).
pub fn encode_gray8_png(
    gray: &[u8],
    width: u32,
    height: u32,
    compression: PngCompression,
    path: &Path,
) -> Result<Vec<u8>> {
    encode_png(
        gray,
        width,
        height,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        compression,
    )
    .map_err(|e| encode_err(e, path))
}

/// PNG of a 16-bit grayscale image (depth).
pub fn encode_gray16_png(
    values: &[u16],
    width: u32,
    height: u32,
    compression: PngCompression,
    path: &Path,
) -> Result<Vec<u8>> {
    // PNG stores 16-bit samples big-endian.
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    encode_png(
        &bytes,
        width,
        height,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        compression,
    )
    .map_err(|e| encode_err(e, path))
}

/// JPEG of an RGB8 image.
pub fn encode_rgb_jpeg(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
    path: &Path,
) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(rgb.len() / 8);
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality.clamp(1, 100))
        .encode(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::Encode {
            message: e.to_string(),
            path: path.to_path_buf(),
        })?;
    Ok(out)
}

fn encode_err(e: png::EncodingError, path: &Path) -> Error {
    Error::Encode {
        message: e.to_string(),
        path: path.to_path_buf(),
    }
}

/// Depth in metres to BOP depth PNG values: `round(depth_mm / depth_scale)` (half to even,
/// as numpy's `round` in bop_toolkit's `save_depth`). 0 stays 0 (no depth); values that do
/// not fit in 16 bits, negative or non-finite depths become 0 (invalid) and are counted.
pub fn depth_to_png_values(depth_m: &[f32], depth_scale: f64) -> (Vec<u16>, u64) {
    let k = 1000.0 / depth_scale;
    let mut overflow = 0u64;
    let values = depth_m
        .iter()
        .map(|&d| {
            if d == 0.0 {
                return 0;
            }
            let v = (d as f64 * k).round_ties_even();
            if v.is_finite() && (0.0..=65535.0).contains(&v) {
                v as u16
            } else {
                overflow += 1;
                0
            }
        })
        .collect();
    (values, overflow)
}

fn decode_err(path: &Path, message: impl Into<String>) -> Error {
    Error::Decode {
        message: message.into(),
        path: path.to_path_buf(),
    }
}

fn decode_png(path: &Path) -> Result<(png::OutputInfo, Vec<u8>)> {
    // Unpack low bit depths and palettes to 8 bits; keep 16 bits as they are.
    decode_png_with(path, png::Transformations::EXPAND)
}

fn decode_png_with(
    path: &Path,
    transformations: png::Transformations,
) -> Result<(png::OutputInfo, Vec<u8>)> {
    let bytes = io::read(path)?;
    let mut dec = png::Decoder::new(Cursor::new(bytes));
    dec.set_transformations(transformations);
    let mut reader = dec
        .read_info()
        .map_err(|e| decode_err(path, e.to_string()))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| decode_err(path, "image too large"))?;
    let mut buf = vec![0u8; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| decode_err(path, e.to_string()))?;
    buf.truncate(info.buffer_size());
    Ok((info, buf))
}

/// Reads a uint16 depth PNG's raw values.
pub fn read_depth_raw(path: &Path) -> Result<Plane<u16>> {
    let (info, buf) = decode_png(path)?;
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(decode_err(
            path,
            format!(
                "expected a 16-bit grayscale depth PNG, found {:?} {:?}",
                info.color_type, info.bit_depth
            ),
        ));
    }
    let data = buf
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    Ok(Plane {
        width: info.width,
        height: info.height,
        data,
    })
}

/// Reads a depth PNG as metres: value × `depth_scale` / 1000; 0 where there is no depth.
pub fn read_depth_m(path: &Path, depth_scale: f64) -> Result<Plane<f32>> {
    let raw = read_depth_raw(path)?;
    let k = depth_scale / 1000.0;
    Ok(Plane {
        width: raw.width,
        height: raw.height,
        data: raw.data.iter().map(|&v| (v as f64 * k) as f32).collect(),
    })
}

/// Reads a mask PNG (8-bit grayscale; of other layouts the first channel, 16 bits scaled
/// down). Values are returned as stored: BOP masks are 0 or 255.
pub fn read_mask(path: &Path) -> Result<Plane<u8>> {
    let (info, buf) = decode_png(path)?;
    let channels = info.color_type.samples();
    let data: Vec<u8> = match info.bit_depth {
        png::BitDepth::Sixteen => buf.chunks_exact(2 * channels).map(|p| p[0]).collect(),
        _ => buf.chunks_exact(channels).map(|p| p[0]).collect(),
    };
    Ok(Plane {
        width: info.width,
        height: info.height,
        data,
    })
}

/// Reads a label PNG (one class index per pixel, as YCB-Video's `-label.png`): 8- or 16-bit
/// grayscale values, or the palette indexes of an indexed 8-bit PNG.
pub fn read_label(path: &Path) -> Result<Plane<u16>> {
    // No EXPAND: a palette image's values are its indexes, not colours.
    let (info, buf) = decode_png_with(path, png::Transformations::IDENTITY)?;
    use png::{BitDepth, ColorType};
    let data: Vec<u16> = match (info.color_type, info.bit_depth) {
        (ColorType::Grayscale | ColorType::Indexed, BitDepth::Eight) => {
            buf.iter().map(|&v| u16::from(v)).collect()
        }
        (ColorType::Grayscale, BitDepth::Sixteen) => buf
            .chunks_exact(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
            .collect(),
        (c, d) => {
            return Err(decode_err(
                path,
                format!("expected an 8- or 16-bit grayscale (or 8-bit indexed) label PNG, found {c:?} {d:?}"),
            ))
        }
    };
    Ok(Plane {
        width: info.width,
        height: info.height,
        data,
    })
}

/// Reads an RGB image (PNG or JPEG) as RGB8.
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    let bytes = io::read(path)?;
    let img = image::load_from_memory(&bytes).map_err(|e| decode_err(path, e.to_string()))?;
    let rgb = img.to_rgb8();
    Ok(RgbImage {
        width: rgb.width(),
        height: rgb.height(),
        rgb: rgb.into_raw(),
    })
}

/// [`read_rgb`] of a dataset frame, refused (an error naming the file) when its size is not
/// the dataset camera's `width × height`: the intrinsics, boxes and masks describe that size.
pub fn read_rgb_sized(path: &Path, size: [u32; 2]) -> Result<RgbImage> {
    let img = read_rgb(path)?;
    if [img.width, img.height] != size {
        return Err(Error::Malformed {
            file: "image".into(),
            message: format!(
                "it is {}x{}, but the dataset's camera (camera.json) is {}x{}",
                img.width, img.height, size[0], size[1]
            ),
            path: path.to_path_buf(),
        });
    }
    Ok(img)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn depth_values_round_half_even_and_overflow() {
        let d = [
            0.0,
            0.00105,
            0.00115,
            1.2345,
            6.5535,
            6.5536,
            -1.0,
            f32::NAN,
        ];
        let (v, overflow) = depth_to_png_values(&d, 0.1);
        // 0.00105 m = 10.5 units (f32 makes it 10.4999...), 1.2345 m = 12345 units.
        assert_eq!(v[0], 0);
        assert!(v[1] == 10 || v[1] == 11);
        assert_eq!(v[3], 12345);
        assert_eq!(v[4], 65535);
        assert_eq!(&v[5..], &[0, 0, 0]);
        assert_eq!(overflow, 3);
        let (v, _) = depth_to_png_values(&[0.0025, 0.0035], 1.0);
        assert_eq!(v, [2, 4], "numpy rounds half to even");
    }

    #[test]
    fn png_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (7u32, 5u32);
        let depth: Vec<u16> = (0..w * h).map(|i| (i * 1871) as u16).collect();
        let p = dir.path().join("d.png");
        for c in [
            PngCompression::Fastest,
            PngCompression::Fast,
            PngCompression::Balanced,
            PngCompression::High,
        ] {
            std::fs::write(&p, encode_gray16_png(&depth, w, h, c, &p).unwrap()).unwrap();
            assert_eq!(read_depth_raw(&p).unwrap().data, depth);
        }
        let mask: Vec<u8> = (0..w * h)
            .map(|i| if i % 3 == 0 { 255 } else { 0 })
            .collect();
        let m = dir.path().join("m.png");
        std::fs::write(
            &m,
            encode_gray8_png(&mask, w, h, PngCompression::Fast, &m).unwrap(),
        )
        .unwrap();
        assert_eq!(read_mask(&m).unwrap().data, mask);
        let e = read_depth_raw(&m).unwrap_err();
        assert!(e.to_string().contains("expected a 16-bit grayscale"), "{e}");
    }
}
