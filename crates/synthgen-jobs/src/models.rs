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

pub use synthgen_formats::identity::model_name;

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

/// Refuses a replacement mesh (`--replay-models`, `--models`) that does not lie where the
/// dataset's model of object `id` lies: its bounding box must match `models_info`'s (min and
/// size) within 5 % of the diameter (3 mm at least). A raw scan in its own origin, or turned,
/// would put every label beside its object; `model align` moves it first. Objects without
/// `models_info` are not checked.
pub fn check_replacement(
    source: &dyn FrameSource,
    id: u32,
    mesh: &std::path::Path,
    replacement: &Model,
    flag: &str,
) -> Result<()> {
    let Some(info) = source.models_info().and_then(|m| m.get(&id)) else {
        return Ok(());
    };
    let Some(bb) = replacement.aabb() else {
        return Ok(());
    };
    let lo = bb.min.as_dvec3() * 1000.0;
    let hi = bb.max.as_dvec3() * 1000.0;
    let want_lo = [info.min_x, info.min_y, info.min_z];
    let want_hi = [
        info.min_x + info.size_x,
        info.min_y + info.size_y,
        info.min_z + info.size_z,
    ];
    let tol = (0.05 * info.diameter).max(3.0);
    let off = (0..3)
        .map(|i| (lo[i] - want_lo[i]).abs().max((hi[i] - want_hi[i]).abs()))
        .fold(0.0_f64, f64::max);
    if off > tol {
        return Err(crate::user_error(
            format!(
                "{flag}: {} does not lie where object {id}'s model lies: its bounding box is ({:.0}, {:.0}, {:.0})..({:.0}, {:.0}, {:.0}) mm, the model's ({:.0}, {:.0}, {:.0})..({:.0}, {:.0}, {:.0}) mm ({off:.0} mm apart, over {tol:.0}): rendered at the GT poses it would sit beside the object",
                mesh.display(),
                lo.x, lo.y, lo.z, hi.x, hi.y, hi.z,
                want_lo[0], want_lo[1], want_lo[2], want_hi[0], want_hi[1], want_hi[2],
            ),
            format!(
                "move the scans onto the models first: synthgen model align --scans DIR --to-dataset {} --out ALIGNED, then {flag} ALIGNED",
                source.root().display()
            ),
        ));
    }
    Ok(())
}
