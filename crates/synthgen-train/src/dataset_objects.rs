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
use crate::metrics::EvalObject;

/// Loads the evaluation model (points, diameter, symmetric) of each object id from the
/// models bop_toolkit scores with: BOP's `models_eval/` when the dataset has it, else its
/// models; every vertex (ADD and ADD-S as bop_toolkit computes them, to the digit).
pub fn load_eval_objects(
    ds: &dyn FrameSource,
    obj_ids: impl IntoIterator<Item = u32>,
) -> Result<BTreeMap<u32, EvalObject>> {
    let (info_path, model_path) = eval_model_paths(ds);
    if info_path == ds.models_info_path() {
        return load_each_object(
            ds.models_info(),
            &ds.models_info_path(),
            &|id| ds.model_file(id),
            ds.model_units(),
            obj_ids,
            eval_object,
        );
    }
    let infos = synthgen_formats::bop::reader::read_models_info(&info_path)?;
    // BOP's models_eval, like its models, are in millimetres.
    load_each_object(
        Some(&infos),
        &info_path,
        &*model_path,
        Units::Mm,
        obj_ids,
        eval_object,
    )
}

/// Whether the metrics of `ds` read other models than its own (`models_eval/`).
pub fn has_eval_models(ds: &dyn FrameSource) -> bool {
    eval_model_paths(ds).0 != ds.models_info_path()
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

/// The evaluation model of an object: every vertex, diameter, symmetric or not.
pub fn eval_object(model: &Model, info: &ModelInfo) -> EvalObject {
    EvalObject {
        points_m: model.positions().map(|p| p.as_dvec3()).collect(),
        diameter_m: info.diameter / 1000.0,
        symmetric: !info.symmetries.is_empty(),
    }
}

/// The models used for the metrics: BOP's `models_eval/` when the dataset has it (as
/// bop_toolkit uses), else the dataset's models. Returns the models_info path and a model
/// path per object.
pub fn eval_model_paths(ds: &dyn FrameSource) -> (PathBuf, Box<dyn Fn(u32) -> PathBuf + '_>) {
    let eval_dir = ds.root().join("models_eval");
    let eval_info = eval_dir.join("models_info.json");
    if eval_info.is_file() {
        return (
            eval_info,
            Box::new(move |id| eval_dir.join(format!("obj_{id:06}.ply"))),
        );
    }
    (ds.models_info_path(), Box::new(|id| ds.model_file(id)))
}
