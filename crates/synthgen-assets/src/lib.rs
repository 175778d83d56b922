//! Mesh loading for synthgen: PLY, OBJ+MTL and glTF/GLB files into `Model`s in metres.
//!
//! Units are explicit (`mm`, `m`, or `auto` by size), every error names the file, missing
//! textures are warnings, and [`write_ply`] writes BOP's millimetre models.
//!
//! ```no_run
//! use std::path::Path;
//! use synthgen_assets::{load_model, write_ply, Units};
//! use synthgen_core::NoProgress;
//!
//! let loaded = load_model(Path::new("models/obj_000008.ply"), Units::Auto, &NoProgress)?;
//! if let Some(note) = &loaded.auto_note {
//!     eprintln!("{note}"); // auto units: obj_000008.ply bbox diagonal 331.2 → millimetres
//! }
//! let size_m = loaded.model.aabb().map(|b| b.size());
//! // BOP stores models in millimetres.
//! write_ply(Path::new("out/models/obj_000008.ply"), &loaded.model, 1000.0)?;
//! # Ok::<(), synthgen_assets::Error>(())
//! ```

mod error;
mod gltf;
mod moved_obj;
mod obj;
mod ply;
mod texture;
mod units;
mod validate;
mod write;

use std::path::Path;

use synthgen_core::{Model, Progress};

pub use error::Error;
pub use moved_obj::{obj_inputs, write_moved_obj};
pub use texture::{load_images_in_dir, load_images_in_dir_strict, TextureCache};
pub use units::{Units, AUTO_MM_THRESHOLD};
pub use write::{write_obj, write_ply};

/// File extensions [`load_model`] understands (lowercase, without the dot).
pub const SUPPORTED_EXTENSIONS: &[&str] = &["ply", "obj", "gltf", "glb"];

/// A model converted to metres, and how its units were decided.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedModel {
    /// Positions in metres.
    pub model: Model,
    /// The units the file was read in: `Mm` or `M`, never `Auto`.
    pub units_used: Units,
    /// With [`Units::Auto`], what was decided and why, for the user to see.
    pub auto_note: Option<String>,
}

/// Loads a model file (`.ply`, `.obj`, `.gltf`, `.glb`), validates it and converts it to
/// metres. Missing textures and material files are warnings through `progress`; the model
/// then uses its flat colour.
pub fn load_model(
    path: &Path,
    units: Units,
    progress: &dyn Progress,
) -> Result<LoadedModel, Error> {
    load_model_cached(path, units, progress, &mut TextureCache::new())
}

/// [`load_model`] sharing decoded textures (and their warnings) across calls.
pub fn load_model_cached(
    path: &Path,
    units: Units,
    progress: &dyn Progress,
    textures: &mut TextureCache,
) -> Result<LoadedModel, Error> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let mut model = match ext.as_str() {
        "ply" => ply::load_ply(path, textures, progress)?,
        "obj" => obj::load_obj(path, textures, progress)?,
        "gltf" | "glb" => gltf::load_gltf(path, textures, progress)?,
        _ => {
            return Err(Error::UnsupportedExtension {
                path: path.to_path_buf(),
            })
        }
    };
    validate::validate_model(&mut model, progress)?;
    let (units_used, auto_note) = units::apply_units(&mut model, units);
    Ok(LoadedModel {
        model,
        units_used,
        auto_note,
    })
}

/// The directory of a model file, canonical when possible, for resolving the files it names
/// (MTL, textures, buffers) and for printing their full paths.
/// Reads a whole mesh file, naming it in the error.
/// Runs a third-party parser, turning a panic on malformed input into an error message.
/// Found by fuzzing: tobj 4.0.5 panics on an MTL colour with fewer than 3 numbers
/// (`Kd 1 0`), gltf-json 1.4.1 on a primitive whose POSITION accessor index is out of range,
/// gltf 1.4.1 on an `unreachable!` in its mesh reader.
pub(crate) fn guard_parser<T>(parser: &str, f: impl FnOnce() -> T) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| {
        let msg = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        format!("the {parser} parser failed on malformed input ({msg})")
    })
}

pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, Error> {
    std::fs::read(path).map_err(|source| Error::Read {
        path: path.to_path_buf(),
        source,
    })
}

pub(crate) fn model_dir(path: &Path) -> std::path::PathBuf {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    dir.canonicalize()
        .or_else(|_| std::path::absolute(dir))
        .unwrap_or_else(|_| dir.to_path_buf())
}

pub(crate) fn file_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}
