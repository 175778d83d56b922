//! Rendering given objects at given poses with nothing else in the scene: what turning real
//! annotated frames into BOP masks and `scene_gt_info`, or YCB-Video labels and vertex maps,
//! needs.

use glam::{DMat3, DVec3};

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

/// The depth of one object alone in a window of the image, millimetres along the optical
/// axis (f32, as bop_toolkit's renderers return it); 0 where the object is not.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DepthWindowMm {
    pub x0: i32,
    pub y0: i32,
    pub width: u32,
    pub height: u32,
    pub depth_mm: Vec<f32>,
}

impl DepthWindowMm {
    /// Depth at image pixel (x, y), 0 outside the window.
    #[inline]
    pub fn at(&self, x: i32, y: i32) -> f32 {
        let (lx, ly) = (x - self.x0, y - self.y0);
        if lx < 0 || ly < 0 || lx >= self.width as i32 || ly >= self.height as i32 {
            return 0.0;
        }
        self.depth_mm[ly as usize * self.width as usize + lx as usize]
    }
}

/// Renders the depth of one object alone, as pose metrics that compare rendered surfaces
/// (BOP's VSD) need: nothing but the depth, precise to well below a micrometre.
pub trait DepthRenderer: Sync {
    /// Depth of object `obj_id` at `cam_from_obj` = (`r`, `t_mm`) on the image of `k`, into
    /// `out`. The rotation is used as given, approximate or not, as bop_toolkit's renderers
    /// use it.
    fn render_depth_mm(
        &self,
        k: &Intrinsics,
        obj_id: u32,
        r: &DMat3,
        t_mm: DVec3,
        out: &mut DepthWindowMm,
    ) -> Result<(), String>;
}
