//! The objects of a dataset as training and scoring need them: each object's `models_info`
//! entry and model file loaded once per id, and what the metrics keep of it (strided points,
//! diameter, symmetric or not).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use synthgen_assets::Units;
use synthgen_core::{Model, NoProgress};
use synthgen_formats::bop::ModelInfo;
use synthgen_formats::source::FrameSource;

use crate::error::{Error, Result};
use crate::metrics::{subsample_vertices, EvalObject};

/// Model points used for ADD / ADD-S (evenly strided vertices).
pub const EVAL_MODEL_POINTS: usize = 1000;

/// Loads the evaluation model (points, diameter, symmetric) of each object id.
pub fn load_eval_objects(
    ds: &dyn FrameSource,
    obj_ids: impl IntoIterator<Item = u32>,
) -> Result<BTreeMap<u32, EvalObject>> {
    load_each_object(
        ds.models_info(),
        &ds.models_info_path(),
        &|id| ds.model_file(id),
        ds.model_units(),
        obj_ids,
        eval_object,
    )
}

/// Loads each distinct object of `obj_ids` once (its models_info entry and its model file,
/// whose numbers are in `units`: millimetres for BOP and Linemod, metres for YCB-Video; the
/// model comes out in metres, or, with `Units::M` on a millimetre file, keeps its
/// millimetres) and keeps what `f` makes of it.
pub fn load_each_object<T>(
    models_info: Option<&BTreeMap<u32, ModelInfo>>,
    info_path: &Path,
    model_path: &dyn Fn(u32) -> PathBuf,
    units: Units,
    obj_ids: impl IntoIterator<Item = u32>,
    mut f: impl FnMut(&Model, &ModelInfo) -> T,
) -> Result<BTreeMap<u32, T>> {
    let infos = models_info.ok_or_else(|| Error::NoModelsInfo {
        path: info_path.to_path_buf(),
    })?;
    let mut out = BTreeMap::new();
    for obj_id in obj_ids {
        if out.contains_key(&obj_id) {
            continue;
        }
        let info = infos.get(&obj_id).ok_or_else(|| Error::UnknownObject {
            obj_id,
            path: info_path.to_path_buf(),
        })?;
        let loaded = synthgen_assets::load_model(&model_path(obj_id), units, &NoProgress)
            .map_err(|source| Error::Model { obj_id, source })?;
        out.insert(obj_id, f(&loaded.model, info));
    }
    Ok(out)
}

/// The evaluation model of an object: strided vertices, diameter, symmetric or not.
pub fn eval_object(model: &Model, info: &ModelInfo) -> EvalObject {
    EvalObject {
        points_m: subsample_vertices(model, EVAL_MODEL_POINTS),
        diameter_m: info.diameter / 1000.0,
        symmetric: !info.symmetries.is_empty(),
    }
}
