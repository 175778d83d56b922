//! Scene extras for `synthgen render`: the distractor models (primitive bank and other
//! meshes) appended after the targets' models, the ground and wall texture images, and the
//! `--sensor` flag's sensor.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result};
use synthgen_assets::Units;
use synthgen_core::distractor::{primitive_models, DistractorPool};
use synthgen_core::sample::SceneObject;
use synthgen_core::scene::{RgbNoiseSpec, SensorSpec};
use synthgen_core::{Model, SceneSpec, Texture};

use crate::commands::user_error;
use crate::Printer;

/// Appends the distractor models of `spec` to `models` and returns the pool that points at
/// them. Empty when `distractors.count` is 0.
pub fn distractor_pool(
    spec: &SceneSpec,
    models: &mut Vec<Model>,
    printer: &Printer,
) -> Result<DistractorPool> {
    let d = &spec.distractors;
    let mut pool = DistractorPool::default();
    if d.count[1] == 0 {
        return Ok(pool);
    }
    let units = match d.units.as_deref() {
        None => Units::Auto,
        Some(u) => u.parse::<Units>().map_err(|_| {
            user_error(
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
        let loaded = synthgen_assets::load_model(path, units, printer)
            .with_context(|| format!("cannot load distractor mesh {}", path.display()))?;
        if let Some(note) = &loaded.auto_note {
            printer.info(note);
        }
        pool.meshes
            .push(SceneObject::new(models.len(), 0, &loaded.model));
        models.push(loaded.model);
    }
    printer.info(format!(
        "{}..{} distractors per frame from {} primitive shapes and {} meshes",
        d.count[0],
        d.count[1],
        pool.primitives.len(),
        pool.meshes.len()
    ));
    Ok(pool)
}

/// Decoded images of a folder.
type Images = Vec<Arc<Texture>>;

/// The images of `ground.texture_dir` and `walls.texture_dir` (each empty when unset),
/// decoded once. A missing or empty folder, or a file in it that does not decode, is an
/// error naming it.
pub fn surface_textures(spec: &SceneSpec, printer: &Printer) -> Result<(Images, Images)> {
    let load = |what: &str, dir: &Option<PathBuf>| -> Result<Images> {
        let Some(dir) = dir else {
            return Ok(Vec::new());
        };
        if !dir.is_dir() {
            return Err(user_error(
                format!("{what}.texture_dir is not a folder: {}", dir.display()),
                "point it at a folder of PNG or JPEG images (relative to the scene file), e.g. the repo's textures/",
            ));
        }
        let images = synthgen_assets::load_images_in_dir_strict(dir)
            .with_context(|| format!("cannot load {what} textures from {}", dir.display()))?;
        if images.is_empty() {
            return Err(user_error(
                format!(
                    "no PNG or JPEG images in {what}.texture_dir {}",
                    dir.display()
                ),
                "put images in the folder, or remove texture_dir from the scene spec",
            ));
        }
        printer.info(format!(
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

/// The sensor of `--sensor NAME|FILE`, which replaces the scene's `sensor` section; the
/// scene's RGB noise stays when the flag's sensor leaves `rgb` at its defaults (a built-in
/// name, or a file without `[rgb]`).
pub fn sensor_flag(arg: &str, scene: &SensorSpec) -> Result<SensorSpec> {
    let mut sensor =
        SensorSpec::from_name_or_file(arg).with_context(|| format!("invalid --sensor {arg}"))?;
    if sensor.rgb == RgbNoiseSpec::default() {
        sensor.rgb = scene.rgb.clone();
    }
    Ok(sensor)
}
