//! What a real dataset (`--real DIR`) offers the experiment before anything is converted or
//! rendered: its frames' scenes (for `--test-scenes`) and its annotated objects with their
//! model files (the synthetic side's objects when no `--objects` is given).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use synthgen_assets::Units;
use synthgen_curate::mix::{scene_list, scene_test_frames, SceneRef};
use synthgen_formats::layout::open_source;
use synthgen_formats::source::FrameLocation;

use crate::user_error;
use crate::Log;

/// The objects the synthetic set is rendered from: `render --objects PATHS --obj-ids IDS`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderObjects {
    pub paths: Vec<PathBuf>,
    /// Empty: `render` picks the ids.
    pub ids: Vec<u32>,
    /// `render --units` (None: its default, auto).
    pub units: Option<&'static str>,
}

/// The frames of a real dataset, in the order `FrameSource::frames` lists them (which is also
/// the order of its BOP conversion).
pub struct RealInventory {
    pub root: PathBuf,
    locations: Vec<FrameLocation>,
    objects: Vec<Vec<u32>>,
    /// Where each annotated object's model file belongs, and whether it is there.
    models: BTreeMap<u32, (PathBuf, bool)>,
    units: Units,
}

impl RealInventory {
    pub fn open(dir: &Path) -> Result<RealInventory> {
        let source = open_source(dir)
            .with_context(|| format!("cannot open the real dataset {}", dir.display()))?;
        let frames = source.frames(&[])?;
        let ids: BTreeSet<u32> = frames.iter().flat_map(|f| f.object_set()).collect();
        Ok(RealInventory {
            root: dir.to_path_buf(),
            locations: frames.iter().map(|f| f.location.clone()).collect(),
            objects: frames.iter().map(|f| f.object_set()).collect(),
            models: ids
                .into_iter()
                .map(|id| (id, (source.model_file(id), source.model_path(id).is_some())))
                .collect(),
            units: source.model_units(),
        })
    }

    pub fn len(&self) -> usize {
        self.locations.len()
    }

    /// The indices of every frame of `scenes`; an unknown scene is bad input that names the
    /// dataset's scenes.
    pub fn test_frames(&self, scenes: &[SceneRef]) -> Result<Vec<usize>> {
        let locations: Vec<&FrameLocation> = self.locations.iter().collect();
        scene_test_frames(&locations, scenes, &self.root).map_err(|e| match e {
            synthgen_formats::Error::UnknownScenes { .. } => user_error(
                format!("--test-scenes: {e}"),
                "pass --test-scenes with ids from that list",
            ),
            e => anyhow::Error::new(e),
        })
    }

    /// Objects annotated in `frames` (all frames when None).
    fn objects_in(&self, frames: Option<&[usize]>) -> BTreeSet<u32> {
        match frames {
            Some(idx) => idx
                .iter()
                .flat_map(|&i| self.objects[i].iter().copied())
                .collect(),
            None => self.objects.iter().flatten().copied().collect(),
        }
    }

    /// The annotated objects that have a model file, to render the synthetic side from, with
    /// their ids and the dataset's model units. The rule for objects without a model file:
    /// one that can be in the test split (any, with a seeded frame split) is an error, since
    /// it would be scored while the synthetic side can never show it; one that appears only in
    /// training scenes is left out of the synthetic set with a warning (real frames still
    /// teach it).
    pub fn render_objects(
        &self,
        test: Option<&[usize]>,
        scenes: &[SceneRef],
        printer: &Log,
    ) -> Result<RenderObjects> {
        let missing: Vec<u32> = self
            .models
            .iter()
            .filter(|(_, (_, present))| !present)
            .map(|(&id, _)| id)
            .collect();
        let scored = self.objects_in(test);
        let (in_test, train_only): (Vec<u32>, Vec<u32>) =
            missing.iter().partition(|id| scored.contains(id));
        let list = |ids: &[u32]| {
            ids.iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        };
        if !in_test.is_empty() {
            let where_ = if test.is_some() {
                format!("the test scene(s) {}", scene_list(scenes))
            } else {
                "the real frames, any of which the test split may draw".to_string()
            };
            return Err(user_error(
                format!(
                    "objects {} are annotated in {where_} but have no model file in {} \
                     (looked for {}); the synthetic set cannot show them, yet they would be scored",
                    list(&in_test),
                    self.root.display(),
                    in_test
                        .iter()
                        .map(|id| self.models[id].0.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                "add the models, hold out scenes without those objects (--test-scenes), or pass \
                 --objects MESH... --obj-ids ID,... yourself",
            ));
        }
        if !train_only.is_empty() {
            printer.warning(format!(
                "objects {} have no model file in {}: left out of the synthetic set (they occur \
                 only in training scenes, so only the real frames teach them)",
                list(&train_only),
                self.root.display()
            ));
        }
        let (ids, paths): (Vec<u32>, Vec<PathBuf>) = self
            .models
            .iter()
            .filter(|(_, (_, present))| *present)
            .map(|(&id, (p, _))| (id, p.clone()))
            .unzip();
        if ids.is_empty() {
            return Err(user_error(
                format!(
                    "no annotated object of the real dataset has a model file: {}",
                    self.root.display()
                ),
                "pass --objects MESH... --obj-ids ID,... to render the synthetic set from",
            ));
        }
        Ok(RenderObjects {
            paths,
            ids,
            units: Some(match self.units {
                Units::M => "m",
                Units::Mm => "mm",
                Units::Auto => "auto",
            }),
        })
    }
}
