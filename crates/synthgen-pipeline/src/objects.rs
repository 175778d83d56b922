//! The target objects of a job: where their meshes come from, their BOP object ids, the
//! sampler's view of them and the symmetries a BOP source's `models_info.json` gives them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use std::sync::Arc;
use synthgen_assets::Units;

use synthgen_core::sample::{RestPose, SceneObject};
use synthgen_core::scene::UpAxis;
use synthgen_core::{Model, Progress, SceneSpec, Symmetries};

use crate::error::{Error, Result};

/// One mesh to load, with where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectSource {
    pub path: PathBuf,
    pub units: Units,
    /// `None`: the id the file name implies (`obj_000008.ply` → 8), else the smallest free.
    pub obj_id: Option<u32>,
    /// Instances of it in every frame's candidate set.
    pub count: u32,
    /// Rest pose for upright placement (`--objects` keep +z).
    pub up: UpAxis,
    pub tilt_deg: f64,
}

impl ObjectSource {
    /// One instance, its id from the file name, standing on its +z axis.
    pub fn new(path: impl Into<PathBuf>, units: Units) -> ObjectSource {
        ObjectSource {
            path: path.into(),
            units,
            obj_id: None,
            count: 1,
            up: UpAxis::PlusZ,
            tilt_deg: 0.0,
        }
    }

    /// The scene spec's `[[objects]]`, in their order; `default_units` where one names none.
    pub fn from_spec(spec: &SceneSpec, default_units: Units) -> Result<Vec<ObjectSource>> {
        spec.objects
            .iter()
            .map(|o| {
                let units = match o.units.as_deref() {
                    None => default_units,
                    Some(u) => u.parse::<Units>().map_err(|_| {
                        Error::invalid(
                            format!(
                                "unknown units {u:?} for {} in the scene spec",
                                o.path.display()
                            ),
                            "use units = \"mm\", \"m\" or \"auto\"",
                        )
                    })?,
                };
                Ok(ObjectSource {
                    path: o.path.clone(),
                    units,
                    obj_id: o.obj_id,
                    count: o.count,
                    up: o.up,
                    tilt_deg: o.tilt_deg,
                })
            })
            .collect()
    }
}

/// Models of different files with the same stem (YCB-Video's `*/textured_simple.obj`) are
/// named after their folder in messages (`025_mug`), so that a summary tells them apart.
pub(crate) fn name_by_folder_where_stems_repeat(models: &mut [Model], sources: &[ObjectSource]) {
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned());
    for i in 0..models.len() {
        let shared = sources
            .iter()
            .any(|o| o.path != sources[i].path && stem(&o.path) == stem(&sources[i].path));
        let folder = sources[i]
            .path
            .parent()
            .and_then(Path::file_name)
            .map(|f| f.to_string_lossy().into_owned());
        if let (true, Some(folder)) = (shared, folder) {
            models[i].name = folder;
        }
    }
}

/// The id a model's path implies: BOP's `obj_000008.ply` (or `obj_08.ply`) → 8; a YCB-Video
/// model (`models/025_mug/textured_simple.obj`) → its class index (14), BOP `ycbv`'s obj_id.
fn id_from_name(path: &Path) -> Option<u32> {
    let stem = path.file_stem()?.to_str()?;
    if let Some(digits) = stem.strip_prefix("obj_") {
        return digits.parse::<u32>().ok().filter(|&v| v > 0);
    }
    ycbv_class_index(path)
}

/// The YCB-Video class index of a model whose folder is named after the class.
pub fn ycbv_class_index(path: &Path) -> Option<u32> {
    let folder = path.parent()?.file_name()?.to_str()?;
    let i = synthgen_formats::ycbv::YCBV_CLASSES
        .iter()
        .position(|c| *c == folder)?;
    u32::try_from(i + 1).ok()
}

/// `classes.txt` of a YCB-Video output: YCB-Video's name for an object whose model sits in
/// that class's folder under that class's id, else `obj_NNNNNN`; ids up to the largest.
pub(crate) fn ycbv_classes(sources: &[ObjectSource], ids: &[u32]) -> Vec<String> {
    let mut names = synthgen_formats::ycbv::class_list(ids, false);
    for (s, &id) in sources.iter().zip(ids) {
        if ycbv_class_index(&s.path) == Some(id) {
            names[id as usize - 1] = synthgen_formats::ycbv::YCBV_CLASSES[id as usize - 1].into();
        }
    }
    names
}

/// Object ids in source order: explicit ids first, then file-name ids, then the smallest free.
pub(crate) fn assign_obj_ids(sources: &[ObjectSource]) -> Result<Vec<u32>> {
    let mut ids: Vec<Option<u32>> = sources
        .iter()
        .map(|s| s.obj_id.or_else(|| id_from_name(&s.path)))
        .collect();
    let mut by_path: BTreeMap<u32, &Path> = BTreeMap::new();
    for (s, id) in sources.iter().zip(&ids) {
        if let Some(id) = id {
            if *id == 0 {
                return Err(Error::invalid(
                    "object id 0 is not allowed",
                    "BOP ids start at 1",
                ));
            }
            match by_path.get(id) {
                Some(p) if *p != s.path.as_path() => {
                    return Err(Error::invalid(
                        format!(
                            "object id {id} is given to both {} and {}",
                            p.display(),
                            s.path.display()
                        ),
                        "pass distinct ids with --obj-ids",
                    ))
                }
                _ => {
                    by_path.insert(*id, &s.path);
                }
            }
        }
    }
    let mut next = 1;
    for (s, id) in sources.iter().zip(ids.iter_mut()) {
        if id.is_none() {
            // The same file listed twice shares one id.
            if let Some((&k, _)) = by_path.iter().find(|(_, p)| **p == s.path.as_path()) {
                *id = Some(k);
                continue;
            }
            while by_path.contains_key(&next) {
                next += 1;
            }
            by_path.insert(next, &s.path);
            *id = Some(next);
        }
    }
    Ok(ids.into_iter().map(|i| i.unwrap_or(0)).collect())
}

pub(crate) fn scene_objects(
    models: &[Model],
    ids: &[u32],
    sources: &[ObjectSource],
) -> Vec<SceneObject> {
    let mut out = Vec::new();
    for (i, ((m, &id), s)) in models.iter().zip(ids).zip(sources).enumerate() {
        let support = m.support_points(256);
        // `up = "stable"`: the rest poses of the mesh's convex hull, computed once per model.
        let rest_poses: Arc<[RestPose]> = if s.up == UpAxis::Stable {
            synthgen_physics::stable_rest_poses(m).into()
        } else {
            Arc::from([])
        };
        for _ in 0..s.count {
            out.push(SceneObject {
                model_index: i,
                obj_id: id,
                name: m.name.clone(),
                support_points_m: support.clone(),
                up: s.up,
                tilt_deg: s.tilt_deg,
                rest_poses: rest_poses.clone(),
            });
        }
    }
    out
}

/// The symmetries of a BOP model (`.../models/obj_000010.ply`) from the `models_info.json`
/// beside it, so a dataset rendered from BOP models keeps them (ADD-S, symmetric losses).
/// `None` for other meshes or when the file has no entry for the object.
pub(crate) fn source_symmetries(
    path: &Path,
    progress: &dyn Progress,
) -> Result<Option<Symmetries>> {
    let Some(id) = path
        .file_stem()
        .and_then(|s| s.to_str())
        .and_then(|s| s.strip_prefix("obj_"))
        .and_then(|s| s.parse::<u32>().ok())
    else {
        return Ok(None);
    };
    let info_path = path.with_file_name("models_info.json");
    if !info_path.is_file() {
        return Ok(None);
    }
    let infos = synthgen_formats::bop::reader::read_models_info(&info_path).map_err(|e| {
        Error::ReadSymmetries {
            path: path.to_path_buf(),
            source: Box::new(e),
        }
    })?;
    let sym = infos.get(&id).map(|i| i.symmetries.clone());
    if let Some(s) = &sym {
        if !s.symmetries_discrete.is_empty() || !s.symmetries_continuous.is_empty() {
            progress.info(&format!(
                "object {id}: symmetries from {}",
                info_path.display()
            ));
        }
    }
    Ok(sym)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn src(p: &str) -> ObjectSource {
        ObjectSource {
            path: PathBuf::from(p),
            units: Units::Auto,
            obj_id: None,
            count: 1,
            up: UpAxis::PlusZ,
            tilt_deg: 0.0,
        }
    }

    #[test]
    fn ids_from_names_then_free_numbers() {
        let s = [
            src("a/obj_000008.ply"),
            src("drill.obj"),
            src("obj_01.ply"),
            src("banana.obj"),
        ];
        assert_eq!(assign_obj_ids(&s).unwrap(), vec![8, 2, 1, 3]);
    }

    #[test]
    fn explicit_ids_win_and_duplicates_are_errors() {
        let with = |ids: [u32; 2]| {
            let mut s = [src("drill.obj"), src("obj_000003.ply")];
            s[0].obj_id = Some(ids[0]);
            s[1].obj_id = Some(ids[1]);
            s
        };
        assert_eq!(assign_obj_ids(&with([5, 6])).unwrap(), vec![5, 6]);
        assert!(assign_obj_ids(&with([5, 5])).is_err());
        let same = [src("drill.obj"), src("drill.obj")];
        assert_eq!(assign_obj_ids(&same).unwrap(), vec![1, 1]);
    }
}
