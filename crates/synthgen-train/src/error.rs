use std::path::PathBuf;

/// Errors of the trainer and evaluator. Messages are lowercase and name the file last.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Dataset(#[from] synthgen_formats::Error),
    #[error("cannot load model of object {obj_id}: {source}")]
    Model {
        obj_id: u32,
        source: synthgen_assets::Error,
    },
    #[error("{path}:{line}: {message}")]
    Csv {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("cannot {op}: {source}: {path}")]
    Io {
        op: &'static str,
        source: std::io::Error,
        path: PathBuf,
    },
    #[error("malformed {what}: {message}: {path}")]
    Malformed {
        what: &'static str,
        message: String,
        path: PathBuf,
    },
    #[error(
        "dataset has no models/models_info.json (diameters and symmetries are needed): {path}"
    )]
    NoModelsInfo { path: PathBuf },
    #[error("object {obj_id} is not in models_info.json: {path}")]
    UnknownObject { obj_id: u32, path: PathBuf },
    #[error("no usable instances ({reason}): {path}")]
    NoInstances { reason: String, path: PathBuf },
    #[error("invalid option: {0}")]
    InvalidOption(String),
    /// The loss stopped being a finite number.
    #[error("training diverged: the loss is {value} at epoch {epoch}, step {step}; {kept}; lower --lr: {path}")]
    Diverged {
        value: f64,
        epoch: usize,
        step: usize,
        /// What is left on disk.
        kept: String,
        path: PathBuf,
    },
    #[error("tensor error: {0}")]
    Candle(#[from] candle_core::Error),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An I/O error of `op` on `path`.
    pub fn io(op: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Error {
        Error::Io {
            op,
            source,
            path: path.into(),
        }
    }
}
