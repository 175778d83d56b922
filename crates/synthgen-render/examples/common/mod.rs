//! What the timing examples share: the rounds argument and the five Linemod benchmark models.

use std::path::PathBuf;

use synthgen_assets::Units;
use synthgen_core::{Model, NoProgress, SceneObject};

/// The first command-line argument as a round count, default 5.
pub fn rounds_arg() -> anyhow::Result<usize> {
    Ok(std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(5))
}

/// Linemod objects 1, 5, 6, 8 and 9 (millimetre PLYs) from `SYNTHGEN_LMO_DIR`, default
/// ../shared/data/lmo next to the repo: the models and their scene objects.
pub fn lmo_models() -> anyhow::Result<(Vec<Model>, Vec<SceneObject>)> {
    let lmo = std::env::var_os("SYNTHGEN_LMO_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/lmo")
        });
    let ids = [1u32, 5, 6, 8, 9];
    let models = ids
        .iter()
        .map(|id| {
            let path = lmo.join(format!("models/obj_{id:06}.ply"));
            synthgen_assets::load_model(&path, Units::Mm, &NoProgress).map(|m| m.model)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let objects = models
        .iter()
        .enumerate()
        .map(|(i, m)| SceneObject::new(i, ids[i], m))
        .collect();
    Ok((models, objects))
}
