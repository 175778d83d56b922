//! Rendering given objects at given poses with nothing else in the scene: what turning real
//! annotated frames into BOP masks and `scene_gt_info`, or YCB-Video labels and vertex maps,
//! needs.

use crate::{Intrinsics, Pose, RenderedFrame};

/// Renders object models, chosen by obj_id, at given poses on an empty background.
/// Implemented by synthgen-render (`ObjectRenderer`), so that dataset code needs no renderer.
pub trait PoseRenderer: Sync {
    /// `objects[i]` = (obj_id, `cam_from_obj`) is instance `i + 1` of the result and has
    /// `alone[i]`. Approximate rotations (read from files) are rendered as their nearest
    /// proper rotation.
    fn render_poses(
        &self,
        k: &Intrinsics,
        objects: &[(u32, Pose)],
    ) -> Result<RenderedFrame, String>;
}
