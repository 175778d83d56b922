//! Errors of the renderers. Messages are lowercase; a model's or texture's source path comes
//! last.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("model {model} has an invalid primitive {primitive}: {reason}: {path}")]
    InvalidModel {
        model: String,
        primitive: usize,
        reason: String,
        path: PathBuf,
    },

    #[error("texture is {width}x{height} but holds {len} bytes (want {want}): {path}")]
    InvalidTexture {
        width: u32,
        height: u32,
        len: usize,
        want: usize,
        path: PathBuf,
    },

    #[error(
        "object {object} refers to model {model_index}, but the renderer has {model_count} models"
    )]
    UnknownModel {
        object: usize,
        model_index: usize,
        model_count: usize,
    },

    #[error("frame has {count} objects; instance ids are u16, so at most {max} fit")]
    TooManyObjects { count: usize, max: usize },

    #[error("invalid camera intrinsics: {reason}")]
    InvalidIntrinsics { reason: String },

    #[error("invalid pose of {what}: {reason}")]
    InvalidPose { what: String, reason: String },

    #[error("background kind \"images\" needs at least one background image, but none were given")]
    NoBackgroundImages,

    #[error("the frame's {what} has an image texture, but the renderer was given no {what} textures (CpuRenderer::with_surface_textures)")]
    NoSurfaceTextures { what: &'static str },

    #[error("invalid render option {name}: {reason}")]
    InvalidOption { name: &'static str, reason: String },

    /// A failure inside another backend (Blender), kept as the error's source.
    #[error("{backend} backend: {source}")]
    Backend {
        backend: &'static str,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}
