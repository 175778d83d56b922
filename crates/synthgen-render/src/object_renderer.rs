//! [`ObjectRenderer`]: the CPU renderer as a [`PoseRenderer`] over a set of models keyed by
//! object id, for annotating and converting real data.

use std::collections::BTreeMap;

use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::sample::ObjectInstance;
use synthgen_core::{
    DepthRenderer, DepthWindowMm, FrameScene, Intrinsics, Model, Pose, PoseRenderer, RenderedFrame,
};

use crate::{CpuRenderer, Error, Renderer};

/// Object models by id, rendered flat-lit on black at the poses asked for.
pub struct ObjectRenderer {
    renderer: CpuRenderer,
    index: BTreeMap<u32, usize>,
}

impl ObjectRenderer {
    /// One model per object id (a repeated id keeps its first model).
    pub fn new(models: Vec<(u32, Model)>) -> Result<ObjectRenderer, Error> {
        let mut index = BTreeMap::new();
        let mut kept = Vec::with_capacity(models.len());
        for (id, m) in models {
            if let std::collections::btree_map::Entry::Vacant(e) = index.entry(id) {
                e.insert(kept.len());
                kept.push(m);
            }
        }
        Ok(ObjectRenderer {
            renderer: CpuRenderer::new(kept, vec![])?,
            index,
        })
    }

    /// The object ids it has models for, sorted.
    pub fn obj_ids(&self) -> Vec<u32> {
        self.index.keys().copied().collect()
    }
}

impl PoseRenderer for ObjectRenderer {
    fn render_poses(
        &self,
        k: &Intrinsics,
        objects: &[(u32, Pose)],
    ) -> Result<RenderedFrame, String> {
        let instances = objects
            .iter()
            .map(|&(obj_id, pose)| {
                let model_index = *self
                    .index
                    .get(&obj_id)
                    .ok_or_else(|| format!("no model for object {obj_id}"))?;
                Ok(ObjectInstance {
                    model_index,
                    obj_id,
                    cam_from_obj: pose.orthonormalized(),
                    brightness: 1.0,
                    specular: 0.0,
                    shininess: 1.0,
                    tint: [1.0; 3],
                    hue_deg: 0.0,
                    metallic: 0.0,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let scene = FrameScene::bare(0, *k, instances);
        self.renderer.render(&scene).map_err(|e| e.to_string())
    }
}

impl DepthRenderer for ObjectRenderer {
    fn render_depth_mm(
        &self,
        k: &Intrinsics,
        obj_id: u32,
        r: &DMat3,
        t_mm: DVec3,
        out: &mut DepthWindowMm,
    ) -> Result<(), String> {
        let model_index = *self
            .index
            .get(&obj_id)
            .ok_or_else(|| format!("no model for object {obj_id}"))?;
        self.renderer
            .render_depth_mm(model_index, r, t_mm, k, out)
            .map_err(|e| e.to_string())
    }
}
