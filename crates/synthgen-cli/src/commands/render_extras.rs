//! Scene extras for `synthgen render`: the distractor models (primitive bank and other
//! meshes) appended after the targets' models.

use anyhow::{Context, Result};
use synthgen_assets::Units;
use synthgen_core::distractor::{primitive_models, DistractorPool};
use synthgen_core::sample::SceneObject;
use synthgen_core::{Model, SceneSpec};

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
