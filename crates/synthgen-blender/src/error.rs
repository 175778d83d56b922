//! Errors of the Blender backend. Messages are lowercase; a path comes last.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// No usable bpy: the venv is missing, has no bpy, or is for another Python.
    #[error("bpy not found: {reason}: {venv}")]
    BpyNotFound { reason: String, venv: PathBuf },

    /// Python raised while importing bpy or building/rendering the scene.
    #[error("blender failed while {action}: {message}")]
    Python { action: String, message: String },

    #[error("cannot read the render passes ({reason}): {path}")]
    Passes { reason: String, path: PathBuf },

    #[error("invalid blender option {name}: {reason}")]
    InvalidOption { name: &'static str, reason: String },

    #[error("the blender render thread stopped: {reason}")]
    ThreadGone { reason: String },

    #[error(transparent)]
    Raster(#[from] synthgen_render::Error),

    #[error("{action}: {source}: {path}")]
    Io {
        action: &'static str,
        source: std::io::Error,
        path: PathBuf,
    },
}

/// The command that creates the default venv; named in every "bpy not found" hint.
pub const SETUP_HINT: &str = "run scripts/setup-blender.sh (creates the venv with bpy 5.0.1), or point --blender-venv / SYNTHGEN_BLENDER_VENV at a venv that has it";
