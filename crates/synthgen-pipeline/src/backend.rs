//! Which renderer draws the frames. `Backend::Blender` always exists; without the `blender`
//! feature it is a clear "not compiled with" error.

use std::path::PathBuf;
use std::sync::Arc;

use synthgen_core::{Model, Progress, Texture};
use synthgen_render::Renderer;

use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq, Default)]
pub enum Backend {
    /// The embedded CPU rasterizer.
    #[default]
    Cpu,
    /// Blender Cycles through bpy (the `blender` feature).
    Blender(BlenderSettings),
}

/// The Blender backend's options.
#[derive(Debug, Clone, PartialEq)]
pub struct BlenderSettings {
    /// The bpy venv; `None`: looked up as docs/blender.md says.
    pub venv: Option<PathBuf>,
    pub samples: u32,
    pub denoise: bool,
    /// Cycles threads; 0 = all cores.
    pub threads: u32,
}

impl Default for BlenderSettings {
    fn default() -> Self {
        BlenderSettings {
            venv: None,
            samples: 16,
            denoise: false,
            threads: 0,
        }
    }
}

impl Backend {
    /// The manifest's name for it (`cpu`, `blender`).
    pub fn name(&self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Blender(_) => "blender",
        }
    }
}

/// The renderer `backend` draws with, for a caller that makes its own frames (`render
/// --replay` renders the real frames' poses): the CPU rasterizer, or Cycles behind the
/// same [`Renderer`] (annotations from Cycles' depth, as a sampled Blender render has).
pub fn renderer_for(
    backend: &Backend,
    models: Vec<Model>,
    backgrounds: Vec<Arc<Texture>>,
    progress: &dyn Progress,
) -> Result<Box<dyn Renderer + Send + Sync>> {
    Ok(match backend {
        Backend::Cpu => Box::new(synthgen_render::CpuRenderer::new(models, backgrounds)?),
        Backend::Blender(settings) => blender_renderer(
            settings,
            models,
            backgrounds,
            [Vec::new(), Vec::new()],
            progress,
        )?,
    })
}

#[cfg(feature = "blender")]
pub(crate) fn blender_renderer(
    settings: &BlenderSettings,
    models: Vec<Model>,
    backgrounds: Vec<Arc<Texture>>,
    surfaces: [Vec<Arc<Texture>>; 2],
    progress: &dyn Progress,
) -> Result<Box<dyn Renderer + Send + Sync>> {
    use synthgen_blender::{BlenderOptions, BlenderRenderer, Error as BlenderError};
    let options = BlenderOptions {
        venv: settings.venv.clone(),
        samples: settings.samples,
        denoise: settings.denoise,
        threads: settings.threads,
        ..BlenderOptions::default()
    };
    progress.info(&format!(
        "starting Blender (Cycles, {} samples{})",
        options.samples,
        if options.denoise { ", denoised" } else { "" }
    ));
    let [ground, walls] = surfaces;
    match BlenderRenderer::with_surfaces(models, backgrounds, ground, walls, options) {
        Ok(r) => Ok(Box::new(r)),
        Err(e @ BlenderError::BpyNotFound { .. }) => {
            Err(Error::invalid(e.to_string(), synthgen_blender::SETUP_HINT))
        }
        Err(e @ BlenderError::InvalidOption { .. }) => {
            Err(Error::invalid(e.to_string(), "see synthgen render --help"))
        }
        Err(e) => Err(Error::Blender(e)),
    }
}

#[cfg(not(feature = "blender"))]
pub(crate) fn blender_renderer(
    _settings: &BlenderSettings,
    _models: Vec<Model>,
    _backgrounds: Vec<Arc<Texture>>,
    _surfaces: [Vec<Arc<Texture>>; 2],
    _progress: &dyn Progress,
) -> Result<Box<dyn Renderer + Send + Sync>> {
    Err(Error::invalid(
        "synthgen was not compiled with the `blender` feature",
        "rebuild with `cargo build -p synthgen-cli --features blender`",
    ))
}
