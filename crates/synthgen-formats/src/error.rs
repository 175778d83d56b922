use std::path::{Path, PathBuf};

/// Errors from reading and writing datasets. Messages name the file last.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("no space left on device: {op} {path}")]
    NoSpace { op: &'static str, path: PathBuf },
    #[error("cannot {op}: {source}: {path}")]
    Io {
        op: &'static str,
        source: std::io::Error,
        path: PathBuf,
    },
    #[error("missing file: {path}")]
    MissingFile { path: PathBuf },
    /// `--force` asked to replace a folder that synthgen did not write.
    #[error("--force replaces an output synthgen wrote (it has a synthgen.json, or an unfinished render's run plan), but this folder holds other files; choose another output folder, or empty it yourself: {path}")]
    ForeignOutput { path: PathBuf },
    /// A dataset folder that does not exist (or is not a folder).
    #[error("no such dataset: {path}")]
    NoSuchDataset { path: PathBuf },
    /// Syntax or type error; serde's message carries the line and column.
    #[error("malformed {file}: {source}: {path}")]
    Json {
        file: String,
        source: serde_json::Error,
        path: PathBuf,
    },
    /// YAML syntax or type error (a missing key, a wrong type); the message carries the
    /// line and column.
    #[error("malformed {file}: {message}: {path}")]
    Yaml {
        file: String,
        message: String,
        path: PathBuf,
    },
    /// Well-formed JSON with wrong content (NaN pose, non-orthonormal rotation, mismatched
    /// counts...).
    #[error("malformed {file}: {message}: {path}")]
    Malformed {
        file: String,
        message: String,
        path: PathBuf,
    },
    #[error("cannot encode image: {message}: {path}")]
    Encode { message: String, path: PathBuf },
    #[error("cannot decode image: {message}: {path}")]
    Decode { message: String, path: PathBuf },
    /// A frame handed to the writer does not fit the dataset (sizes, counts, values).
    #[error("invalid frame {frame_index}: {message}")]
    InvalidFrame { frame_index: u64, message: String },
    #[error("invalid writer options: {0}")]
    InvalidOptions(String),
    /// A draw asked for more frames than a dataset has.
    #[error("asked for {asked} {what} frames but only {available} are available{note}: {path}")]
    NotEnoughFrames {
        what: String,
        asked: usize,
        available: usize,
        /// Extra detail such as how many frames the test split holds back.
        note: String,
        path: PathBuf,
    },
    /// Test scenes (`--test-scenes`) that no frame of the dataset belongs to.
    #[error("no scene {asked} in the dataset; its scenes are {available}: {path}")]
    UnknownScenes {
        asked: String,
        available: String,
        path: PathBuf,
    },
    /// Options of a command that do not fit together (counts, ratios).
    #[error("{0}")]
    InvalidRequest(String),
    /// A model file that cannot be loaded or written (the message names the file).
    #[error("{source}")]
    Model {
        source: synthgen_assets::Error,
        path: PathBuf,
    },
    /// Another process holds the output folder's lock ([`crate::output::OutputLock`]).
    #[error("another synthgen process is writing to this folder (it holds {}); wait for it to finish, or choose another output folder: {path}", .lock.display())]
    Locked { lock: PathBuf, path: PathBuf },
    /// A value that JSON cannot hold (NaN, infinity) in data to be written.
    #[error("cannot write non-finite number in {what}: {path}")]
    NonFinite { what: String, path: PathBuf },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

fn is_no_space(e: &std::io::Error) -> bool {
    // ENOSPC on Linux and macOS; ERROR_HANDLE_DISK_FULL / ERROR_DISK_FULL on Windows.
    let code = e.raw_os_error();
    if cfg!(windows) {
        matches!(code, Some(39) | Some(112))
    } else {
        code == Some(28)
    }
}

impl Error {
    /// An io error while doing `op` ("write", "read", ...) on `path`.
    pub fn io(op: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Error {
        let path = path.into();
        if source.kind() == std::io::ErrorKind::NotFound && op == "read" {
            return Error::MissingFile { path };
        }
        if is_no_space(&source) {
            let op = match op {
                "write" => "writing",
                "rename" => "renaming",
                "create directory" => "creating directory",
                other => other,
            };
            return Error::NoSpace { op, path };
        }
        Error::Io { op, source, path }
    }

    pub fn json(path: &Path, source: serde_json::Error) -> Error {
        Error::Json {
            file: file_name(path),
            source,
            path: path.to_path_buf(),
        }
    }

    pub fn yaml(path: &Path, source: serde_yaml_ng::Error) -> Error {
        Error::Yaml {
            file: file_name(path),
            message: source.to_string(),
            path: path.to_path_buf(),
        }
    }

    pub fn model(path: &Path, source: synthgen_assets::Error) -> Error {
        Error::Model {
            source,
            path: path.to_path_buf(),
        }
    }

    pub fn malformed(path: &Path, message: impl Into<String>) -> Error {
        Error::Malformed {
            file: file_name(path),
            message: message.into(),
            path: path.to_path_buf(),
        }
    }

    /// The file the error is about, when there is one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            Error::NoSpace { path, .. }
            | Error::Io { path, .. }
            | Error::MissingFile { path }
            | Error::NoSuchDataset { path }
            | Error::ForeignOutput { path }
            | Error::Json { path, .. }
            | Error::Malformed { path, .. }
            | Error::Yaml { path, .. }
            | Error::Encode { path, .. }
            | Error::Decode { path, .. }
            | Error::NonFinite { path, .. }
            | Error::Model { path, .. }
            | Error::Locked { path, .. }
            | Error::NotEnoughFrames { path, .. }
            | Error::UnknownScenes { path, .. } => Some(path),
            Error::InvalidFrame { .. } | Error::InvalidOptions(_) | Error::InvalidRequest(_) => {
                None
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn no_space_is_named() {
        let e = Error::io(
            "write",
            "/data/x.png",
            std::io::Error::from_raw_os_error(if cfg!(windows) { 112 } else { 28 }),
        );
        assert_eq!(
            e.to_string(),
            "no space left on device: writing /data/x.png"
        );
    }

    #[test]
    fn missing_file_on_read() {
        let e = Error::io("read", "/nope", std::io::ErrorKind::NotFound.into());
        assert_eq!(e.to_string(), "missing file: /nope");
    }
}
