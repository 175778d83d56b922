//! Scene extras: the distractor models (primitive bank and other meshes) appended after the
//! targets' models, the background images, and the ground and wall texture images.

use std::path::PathBuf;
use std::sync::Arc;

use synthgen_assets::Units;
use synthgen_core::distractor::{primitive_models, DistractorPool};
use synthgen_core::sample::SceneObject;
use synthgen_core::scene::BackgroundKind;
use synthgen_core::{Model, Progress, SceneSpec, Texture};

use crate::error::{Error, Result};

/// Decoded images of a folder.
pub(crate) type Images = Vec<Arc<Texture>>;

/// Appends the distractor models of `spec` to `models` and returns the pool that points at
/// them. Empty when `distractors.count` is 0.
pub(crate) fn distractor_pool(
    spec: &SceneSpec,
    models: &mut Vec<Model>,
    progress: &dyn Progress,
) -> Result<DistractorPool> {
    let d = &spec.distractors;
    let mut pool = DistractorPool::default();
    if d.count[1] == 0 {
        return Ok(pool);
    }
    let units = match d.units.as_deref() {
        None => Units::Auto,
        Some(u) => u.parse::<Units>().map_err(|_| {
            Error::invalid(
                format!("unknown distractors.units {u:?} in the scene spec"),
                "use units = \"mm\", \"m\" or \"auto\"",
            )
        })?,
    };
    for m in primitive_models(d) {
        pool.primitives.push(SceneObject::new(models.len(), 0, &m));
        models.push(m);
    }
    for path in &d.meshes {
        let loaded = synthgen_assets::load_model(path, units, progress).map_err(|e| {
            Error::LoadDistractor {
                path: path.clone(),
                source: Box::new(e),
            }
        })?;
        if let Some(note) = &loaded.auto_note {
            progress.info(note);
        }
        pool.meshes
            .push(SceneObject::new(models.len(), 0, &loaded.model));
        models.push(loaded.model);
    }
    progress.info(&format!(
        "{}..{} distractors per frame from {} primitive shapes and {} meshes",
        d.count[0],
        d.count[1],
        pool.primitives.len(),
        pool.meshes.len()
    ));
    Ok(pool)
}

/// The background images of `background.kind = "images"`; empty for the other kinds.
pub(crate) fn backgrounds(spec: &SceneSpec, progress: &dyn Progress) -> Result<Images> {
    if spec.background.kind != BackgroundKind::Images {
        return Ok(Vec::new());
    }
    let Some(dir) = &spec.background.images_dir else {
        return Ok(Vec::new());
    };
    let images =
        synthgen_assets::load_images_in_dir(dir, progress).map_err(|e| Error::LoadBackgrounds {
            path: dir.clone(),
            source: Box::new(e),
        })?;
    if images.is_empty() {
        return Err(Error::invalid(
            format!("no PNG or JPEG images in {}", dir.display()),
            "point --background-dir at a folder of images, or use --background noise",
        ));
    }
    progress.info(&format!(
        "{} background images from {}",
        images.len(),
        dir.display()
    ));
    Ok(images)
}

/// The images of `ground.texture_dir` and `walls.texture_dir` (each empty when unset),
/// decoded once. A missing or empty folder, or a file in it that does not decode, is an
/// error naming it.
pub(crate) fn surface_textures(
    spec: &SceneSpec,
    progress: &dyn Progress,
) -> Result<(Images, Images)> {
    let load = |what: &'static str, dir: &Option<PathBuf>| -> Result<Images> {
        let Some(dir) = dir else {
            return Ok(Vec::new());
        };
        if !dir.is_dir() {
            return Err(Error::invalid(
                format!("{what}.texture_dir is not a folder: {}", dir.display()),
                "point it at a folder of PNG or JPEG images (relative to the scene file), e.g. the repo's textures/",
            ));
        }
        let images =
            synthgen_assets::load_images_in_dir_strict(dir).map_err(|e| Error::LoadTextures {
                what,
                path: dir.clone(),
                source: Box::new(e),
            })?;
        if images.is_empty() {
            return Err(Error::invalid(
                format!(
                    "no PNG or JPEG images in {what}.texture_dir {}",
                    dir.display()
                ),
                "put images in the folder, or remove texture_dir from the scene spec",
            ));
        }
        progress.info(&format!(
            "{} {what} textures from {}",
            images.len(),
            dir.display()
        ));
        Ok(images)
    };
    Ok((
        load("ground", &spec.ground.texture_dir)?,
        load("walls", &spec.walls.texture_dir)?,
    ))
}
