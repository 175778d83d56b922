//! Texture loading with a cache (one decode per file) and the fall-back-with-a-warning rule.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use synthgen_core::glam::Vec2;
use synthgen_core::{Progress, Texture};

use crate::Error;

/// Decoded textures by path, so a file used by several materials or models is decoded once.
/// A failed load is remembered too, so its warning is given once.
#[derive(Debug, Default)]
pub struct TextureCache {
    by_path: HashMap<PathBuf, Option<Arc<Texture>>>,
}

impl TextureCache {
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of files tried so far (loaded or not).
    pub fn len(&self) -> usize {
        self.by_path.len()
    }

    pub fn is_empty(&self) -> bool {
        self.by_path.is_empty()
    }

    /// Loads `path` (an 8-bit or 16-bit PNG or JPEG; alpha is dropped). When it is missing or
    /// unreadable, warns once (`texture not found, using {fallback}: {path}`) and returns `None`.
    pub fn load(
        &mut self,
        path: &Path,
        fallback: &str,
        progress: &dyn Progress,
    ) -> Option<Arc<Texture>> {
        let path = full_path(path);
        if let Some(t) = self.by_path.get(&path) {
            return t.clone();
        }
        let loaded = match decode_file(&path) {
            Ok(t) => Some(Arc::new(t)),
            Err(DecodeError::Missing) => {
                progress.warn(&format!(
                    "texture not found, using {fallback}: {}",
                    path.display()
                ));
                None
            }
            Err(DecodeError::Unreadable(reason)) => {
                progress.warn(&format!(
                    "texture unreadable ({reason}), using {fallback}: {}",
                    path.display()
                ));
                None
            }
        };
        self.by_path.insert(path, loaded.clone());
        loaded
    }
}

/// Loads every PNG and JPEG image in `dir` (not recursive), sorted by file name so the order
/// (and any seeded choice among them) is reproducible. An unreadable image is a warning and is
/// skipped; an unreadable directory is an error. An empty result is for the caller to judge.
pub fn load_images_in_dir(dir: &Path, progress: &dyn Progress) -> Result<Vec<Arc<Texture>>, Error> {
    let paths = image_paths(dir)?;
    let mut images = Vec::with_capacity(paths.len());
    for path in paths {
        match decode_file(&path) {
            Ok(t) => images.push(Arc::new(t)),
            Err(DecodeError::Missing) => {
                progress.warn(&format!("image vanished, skipped: {}", path.display()))
            }
            Err(DecodeError::Unreadable(reason)) => progress.warn(&format!(
                "image unreadable ({reason}), skipped: {}",
                path.display()
            )),
        }
    }
    Ok(images)
}

/// The PNG and JPEG files of `dir` (by extension, not recursive), sorted by name.
fn image_paths(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let read_err = |source| Error::Read {
        path: dir.to_path_buf(),
        source,
    };
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(read_err)? {
        let path = entry.map_err(read_err)?.path();
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if matches!(ext.as_str(), "png" | "jpg" | "jpeg") && path.is_file() {
            paths.push(path);
        }
    }
    paths.sort();
    Ok(paths)
}

/// Like [`load_images_in_dir`], but every PNG or JPEG file of `dir` must decode: the first
/// that does not is an error naming it (for texture folders, where a silently skipped file
/// would change which image a frame draws). An empty result is for the caller to judge.
pub fn load_images_in_dir_strict(dir: &Path) -> Result<Vec<Arc<Texture>>, Error> {
    image_paths(dir)?
        .into_iter()
        .map(|path| match decode_file(&path) {
            Ok(t) => Ok(Arc::new(t)),
            Err(DecodeError::Missing) => Err(Error::Image {
                reason: "vanished while reading the folder".into(),
                path,
            }),
            Err(DecodeError::Unreadable(reason)) => Err(Error::Image { reason, path }),
        })
        .collect()
}

/// The path users should see in messages: canonical when the file or at least its directory
/// exists (no `..` left), else merely absolute.
fn full_path(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    if let (Some(dir), Some(name)) = (path.parent(), path.file_name()) {
        if let Ok(d) = dir.canonicalize() {
            return d.join(name);
        }
    }
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

enum DecodeError {
    Missing,
    Unreadable(String),
}

fn decode_file(path: &Path) -> Result<Texture, DecodeError> {
    if !path.is_file() {
        return Err(DecodeError::Missing);
    }
    let img = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| DecodeError::Unreadable(e.to_string()))?
        .decode()
        .map_err(|e| DecodeError::Unreadable(e.to_string()))?;
    let rgb = img.to_rgb8();
    Ok(Texture {
        width: rgb.width(),
        height: rgb.height(),
        rgb: rgb.into_raw(),
        source: path.to_path_buf(),
    })
}

/// Bilinear sample of an sRGB texture at `uv` (`v = 0` is the first row), wrapping around like
/// OpenGL's `REPEAT`; returns sRGB in 0..1.
pub(crate) fn sample_bilinear(tex: &Texture, uv: Vec2) -> [f32; 3] {
    let (w, h) = (tex.width as usize, tex.height as usize);
    if w == 0 || h == 0 || tex.rgb.len() < w * h * 3 {
        return [1.0; 3];
    }
    let x = uv.x.rem_euclid(1.0) * w as f32 - 0.5;
    let y = uv.y.rem_euclid(1.0) * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let wrap = |i: f32, n: usize| (i as i64).rem_euclid(n as i64) as usize;
    let (xa, xb) = (wrap(x0, w), wrap(x0 + 1.0, w));
    let (ya, yb) = (wrap(y0, h), wrap(y0 + 1.0, h));
    let px = |x: usize, y: usize, c: usize| f32::from(tex.rgb[(y * w + x) * 3 + c]);
    let mut out = [0.0; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let top = px(xa, ya, c) * (1.0 - fx) + px(xb, ya, c) * fx;
        let bottom = px(xa, yb, c) * (1.0 - fx) + px(xb, yb, c) * fx;
        *o = (top * (1.0 - fy) + bottom * fy) / 255.0;
    }
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_sample_hits_texel_centres() {
        // 2x1: red then blue.
        let tex = Texture {
            width: 2,
            height: 1,
            rgb: vec![255, 0, 0, 0, 0, 255],
            source: PathBuf::new(),
        };
        assert_eq!(sample_bilinear(&tex, Vec2::new(0.25, 0.5)), [1.0, 0.0, 0.0]);
        assert_eq!(sample_bilinear(&tex, Vec2::new(0.75, 0.5)), [0.0, 0.0, 1.0]);
        assert_eq!(sample_bilinear(&tex, Vec2::new(0.5, 0.5)), [0.5, 0.0, 0.5]);
    }

    #[test]
    fn missing_texture_warns_once_and_is_cached() {
        struct Count(std::sync::Mutex<Vec<String>>);
        impl Progress for Count {
            fn warn(&self, m: &str) {
                self.0.lock().unwrap().push(m.to_string());
            }
        }
        let p = Count(Default::default());
        let mut cache = TextureCache::new();
        let missing = Path::new("/nonexistent/dir/tex.png");
        assert!(cache.load(missing, "the Kd colour", &p).is_none());
        assert!(cache.load(missing, "the Kd colour", &p).is_none());
        let w = p.0.lock().unwrap();
        assert_eq!(
            *w,
            vec!["texture not found, using the Kd colour: /nonexistent/dir/tex.png".to_string()]
        );
    }
}
