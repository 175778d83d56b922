//! Errors of mesh loading and writing. Every message names the file last.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot read file ({source}): {path}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },

    #[error("cannot write file ({source}): {path}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },

    #[error("unsupported model format (supported: {}): {path}", crate::SUPPORTED_EXTENSIONS.join(", "))]
    UnsupportedExtension { path: PathBuf },

    #[error("unsupported ply ({reason}): {path}")]
    UnsupportedPly { reason: String, path: PathBuf },

    #[error("malformed ply header, line {line}: {reason}: {path}")]
    PlyHeader {
        line: usize,
        reason: String,
        path: PathBuf,
    },

    /// A bad body value. `line` is the 1-based line of an ASCII file (none for binary).
    #[error("malformed ply {element} {index}{}: {reason}: {path}", line_suffix(.line))]
    PlyBody {
        element: String,
        index: usize,
        line: Option<usize>,
        reason: String,
        path: PathBuf,
    },

    #[error("ply body truncated: file ends in {element} {index} of {count}: {path}")]
    PlyTruncated {
        element: String,
        index: usize,
        count: usize,
        path: PathBuf,
    },

    #[error("mesh has no faces: {path}")]
    NoFaces { path: PathBuf },

    #[error("vertex {vertex} has a non-finite coordinate (NaN or infinity): {path}")]
    NonFiniteVertex { vertex: usize, path: PathBuf },

    /// `face` is the face element index in a PLY file, the triangle index otherwise.
    #[error(
        "face {face} refers to vertex {index} but the mesh has {vertex_count} vertices: {path}"
    )]
    IndexOutOfRange {
        face: usize,
        index: i64,
        vertex_count: usize,
        path: PathBuf,
    },

    #[error("cannot decode image ({reason}): {path}")]
    Image { reason: String, path: PathBuf },

    #[error("cannot parse obj ({reason}): {path}")]
    Obj { reason: String, path: PathBuf },

    #[error("cannot load gltf ({reason}): {path}")]
    Gltf { reason: String, path: PathBuf },

    /// An output folder that is, or holds, a file the command reads.
    #[error("the output {relation} the input {}: a command never writes over its inputs; choose another output folder: {path}", .input.display())]
    OutputOverInput {
        relation: &'static str,
        input: PathBuf,
        path: PathBuf,
    },

    #[error("unknown units {value:?} (expected mm, m or auto)")]
    UnknownUnits { value: String },
}

fn line_suffix(line: &Option<usize>) -> String {
    match line {
        Some(l) => format!(" (line {l})"),
        None => String::new(),
    }
}
