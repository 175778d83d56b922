//! The object models of a dataset loaded into an [`ObjectRenderer`], for the steps that
//! render real frames at their GT poses (annotate, convert, the fits, render --replay), and
//! the replacement meshes of `render --replay-models` and `sim2real --models`.

use anyhow::{Context, Result};
use synthgen_core::Model;
use synthgen_formats::source::FrameSource;
use synthgen_render::ObjectRenderer;

use synthgen_core::Progress;

/// Loads the model of every object in `obj_ids` from the dataset's model files (in the
/// dataset's units; a missing texture is a warning, a missing model an error naming it).
pub fn object_renderer(
    source: &dyn FrameSource,
    obj_ids: &[u32],
    progress: &dyn Progress,
) -> Result<ObjectRenderer> {
    Ok(ObjectRenderer::new(load_models(
        source, obj_ids, progress,
    )?)?)
}

/// The models of `obj_ids` (metres), in that order, as [`object_renderer`] loads them.
pub fn load_models(
    source: &dyn FrameSource,
    obj_ids: &[u32],
    progress: &dyn Progress,
) -> Result<Vec<(u32, Model)>> {
    let mut models = Vec::with_capacity(obj_ids.len());
    for &id in obj_ids {
        let model = source
            .load_model(id, progress)
            .with_context(|| format!("cannot load the model of object {id}"))?;
        models.push((id, model));
    }
    Ok(models)
}

/// The distinct object ids of the frames, sorted.
pub fn frame_obj_ids(frames: &[synthgen_formats::source::SourceFrame]) -> Vec<u32> {
    let mut ids: Vec<u32> = frames.iter().flat_map(|f| f.object_set()).collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// How the dataset names object `id`'s model: YCB-Video's class folder
/// (`models/<class>/textured_simple.obj`), else the file stem (`obj_000005`).
pub fn model_name(source: &dyn FrameSource, id: u32) -> String {
    let file = source.model_file(id);
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned());
    match (stem.as_deref(), file.parent().and_then(|p| p.file_name())) {
        (Some("textured_simple" | "textured"), Some(class)) => class.to_string_lossy().into_owned(),
        (Some(stem), _) => stem.to_string(),
        _ => format!("obj_{id:06}"),
    }
}

/// The files of `folder` whose extension is one of `extensions` (any case), sorted.
pub fn files_with_extensions(
    folder: &std::path::Path,
    extensions: &[&str],
) -> std::io::Result<Vec<std::path::PathBuf>> {
    let mut v: Vec<std::path::PathBuf> = std::fs::read_dir(folder)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|e| {
                extensions
                    .iter()
                    .any(|x| e.to_string_lossy().eq_ignore_ascii_case(x))
            })
        })
        .collect();
    v.sort();
    Ok(v)
}

/// The replacement meshes `flag` (`--replay-models`, `--models`) names for `ids`: per object
/// the one mesh in `dir/<its name>/` (`model_name`), None where it has no folder there. A
/// `dir` that is not a folder, or an object folder with other than one mesh, is an error.
/// Also the names of the objects without a folder.
#[allow(clippy::type_complexity)]
pub fn replacement_meshes(
    source: &dyn FrameSource,
    dir: &std::path::Path,
    ids: impl IntoIterator<Item = u32>,
    flag: &str,
) -> Result<(Vec<Option<std::path::PathBuf>>, Vec<String>)> {
    if !dir.is_dir() {
        return Err(crate::user_error(
            format!("{flag} is not a folder: {}", dir.display()),
            "give a folder with one subfolder per object (`synthgen model align --scans` writes one)",
        ));
    }
    let mut meshes = Vec::new();
    let mut kept = Vec::new();
    for id in ids {
        let name = model_name(source, id);
        let folder = dir.join(&name);
        if !folder.is_dir() {
            kept.push(name);
            meshes.push(None);
            continue;
        }
        let found = files_with_extensions(&folder, synthgen_assets::SUPPORTED_EXTENSIONS)
            .with_context(|| format!("cannot read {}", folder.display()))?;
        let [mesh] = found.as_slice() else {
            return Err(crate::user_error(
                format!(
                    "{} holds {} meshes; {flag} needs exactly one per object folder",
                    folder.display(),
                    found.len()
                ),
                "keep one mesh (.obj, .ply, .gltf, .glb) in each object's folder",
            ));
        };
        meshes.push(Some(mesh.clone()));
    }
    Ok((meshes, kept))
}
