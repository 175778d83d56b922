//! synthgen's Blender backend: the same `Renderer` as the CPU rasterizer, but the pixels come
//! from Cycles (bpy, Blender as a Python module, embedded through PyO3).
//!
//! The camera conversion ([`camera`]), the venv lookup ([`venv`]) and the pass decoding
//! ([`passes`]) are plain Rust and always built; the renderer itself needs the cargo feature
//! `blender` (PyO3 + libpython 3.11) and, at run time, a venv with `bpy` 5.0.1
//! (`scripts/setup-blender.sh`). See docs/blender.md.
//!
//! ```no_run
//! # #[cfg(feature = "blender")] {
//! use synthgen_blender::{BlenderOptions, BlenderRenderer};
//! use synthgen_render::Renderer;
//! # fn scene() -> synthgen_core::FrameScene { unimplemented!() }
//! let models = vec![synthgen_core::Model::cuboid("box", synthgen_core::glam::Vec3::splat(0.1))];
//! let renderer = BlenderRenderer::new(models, vec![], BlenderOptions::default())?;
//! let frame = renderer.render(&scene())?; // Cycles RGB and depth, object-index instances
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod camera;
mod error;
#[cfg(feature = "blender")]
mod exr_passes;
pub mod passes;
#[cfg(feature = "blender")]
mod renderer;
pub mod venv;

pub use error::{Error, SETUP_HINT};
#[cfg(feature = "blender")]
pub use renderer::{
    frame_json, frame_json_with, BlenderRenderer, SurfaceAspects, WATTS_PER_IRRADIANCE_AT_1M,
};

use std::path::PathBuf;

/// Whether this build can render through Blender.
pub const COMPILED: bool = cfg!(feature = "blender");

/// Cycles settings of the Blender backend.
#[derive(Debug, Clone, PartialEq)]
pub struct BlenderOptions {
    /// The venv holding bpy (default: [`venv::resolve_venv`]).
    pub venv: Option<PathBuf>,
    /// Path-tracing samples per pixel. Default 16.
    pub samples: u32,
    /// Denoise with OpenImageDenoise (in the bpy wheel). Default off.
    pub denoise: bool,
    /// CPU threads for Cycles; 0 = all cores. Default 0.
    pub threads: u32,
    /// Pixel filter (Blackman-Harris) width in pixels, for the anti-aliasing of the RGB.
    /// Default 1.5 (Blender's). With it the Object Index and Z passes still match the raster
    /// backend's pixel-centre masks (IoU >= 0.998 in the agreement tests).
    pub filter_width_px: f32,
    /// Where the per-frame EXR is written and read back (default: a folder in the temp dir).
    pub scratch_dir: Option<PathBuf>,
}

impl Default for BlenderOptions {
    fn default() -> Self {
        Self {
            venv: None,
            samples: 16,
            denoise: false,
            threads: 0,
            filter_width_px: 1.5,
            scratch_dir: None,
        }
    }
}

impl BlenderOptions {
    pub fn validate(&self) -> Result<(), Error> {
        if self.samples == 0 || self.samples > 1 << 24 {
            return Err(Error::InvalidOption {
                name: "samples",
                reason: format!("must be 1..=16777216, got {}", self.samples),
            });
        }
        if !(self.filter_width_px.is_finite() && (0.01..=10.0).contains(&self.filter_width_px)) {
            return Err(Error::InvalidOption {
                name: "filter_width_px",
                reason: format!("must be in 0.01..=10, got {}", self.filter_width_px),
            });
        }
        Ok(())
    }

    /// The settings for `setup` in blender/synthgen_scene.py, as JSON.
    pub fn settings_json(&self) -> String {
        format!(
            "{{\"samples\": {}, \"denoise\": {}, \"threads\": {}, \"filter_width_px\": {}}}",
            self.samples, self.denoise, self.threads, self.filter_width_px
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_validate() {
        assert!(BlenderOptions::default().validate().is_ok());
        let bad = BlenderOptions {
            samples: 0,
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().to_string().contains("samples"));
        let bad = BlenderOptions {
            filter_width_px: 0.0,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
    }
}
