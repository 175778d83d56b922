use std::path::PathBuf;

/// What can go wrong preparing a render job, rendering a frame or writing a dataset.
///
/// The wrapped errors of the other crates are transparent: messages and their causes read as
/// they do where those crates are called directly.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A problem with what was asked for (objects, ids, a folder), with what to do instead.
    #[error("{message}")]
    Invalid { message: String, hint: String },

    #[error("cannot load object {path}")]
    LoadObject {
        path: PathBuf,
        #[source]
        source: Box<synthgen_assets::Error>,
    },

    #[error("cannot load distractor mesh {path}")]
    LoadDistractor {
        path: PathBuf,
        #[source]
        source: Box<synthgen_assets::Error>,
    },

    #[error("cannot load background images from {path}")]
    LoadBackgrounds {
        path: PathBuf,
        #[source]
        source: Box<synthgen_assets::Error>,
    },

    #[error("cannot load {what} textures from {path}")]
    LoadTextures {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: Box<synthgen_assets::Error>,
    },

    #[error("cannot read the symmetries of {path}")]
    ReadSymmetries {
        path: PathBuf,
        #[source]
        source: Box<synthgen_formats::Error>,
    },

    #[error("cannot write model {path}")]
    WriteModel {
        path: PathBuf,
        #[source]
        source: Box<synthgen_assets::Error>,
    },

    #[error("cannot read {path}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    #[error("cannot remove {path}")]
    Remove {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    #[error("malformed {path}")]
    Malformed {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },

    #[error("cannot serialize {what}")]
    Serialize {
        what: &'static str,
        #[source]
        source: serde_json::Error,
    },

    #[error("cannot start worker threads")]
    ThreadPool(#[source] rayon::ThreadPoolBuildError),

    #[cfg(feature = "blender")]
    #[error("cannot start the blender backend")]
    Blender(#[source] synthgen_blender::Error),

    /// A bug, or an option combination the CLI refuses before it gets here.
    #[error("{0}")]
    Internal(String),

    #[error(transparent)]
    Core(#[from] synthgen_core::Error),

    #[error(transparent)]
    Assets(#[from] synthgen_assets::Error),

    #[error(transparent)]
    Dataset(#[from] synthgen_formats::Error),

    #[error(transparent)]
    Render(#[from] synthgen_render::Error),

    #[error(transparent)]
    Physics(#[from] synthgen_physics::Error),
}

impl Error {
    pub(crate) fn invalid(message: impl Into<String>, hint: impl Into<String>) -> Error {
        Error::Invalid {
            message: message.into(),
            hint: hint.into(),
        }
    }

    /// What to do about it, for the errors that come with a hint.
    pub fn hint(&self) -> Option<&str> {
        match self {
            Error::Invalid { hint, .. } => Some(hint),
            _ => None,
        }
    }

    /// Whether this error comes from the input (exit code 1) rather than from a bug: what was
    /// asked for, the files read (meshes, images, a models_info) or written. The causes of
    /// the others are for the caller to look at (a `Read`'s is the I/O error).
    pub fn is_user_error(&self) -> bool {
        matches!(
            self,
            Error::Invalid { .. }
                | Error::LoadObject { .. }
                | Error::LoadDistractor { .. }
                | Error::LoadBackgrounds { .. }
                | Error::LoadTextures { .. }
                | Error::ReadSymmetries { .. }
                | Error::WriteModel { .. }
                | Error::Core(_)
                | Error::Assets(_)
                | Error::Dataset(_)
        )
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
