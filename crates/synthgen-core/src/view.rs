//! View rejection: a sampled camera is kept only when every target is visible enough
//! (`camera.min_visib_fract`) and, unless `camera.allow_truncation`, inside the image.

use glam::DVec3;

use crate::frame_scene::{FrameScene, SceneObject};

/// Pixel counts of one object in a frame, as BOP counts them (`synthgen_core::annotate`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Visibility {
    /// Silhouette pixels on the canvas three times the image (BOP `px_count_all`).
    pub px_all: u64,
    /// Silhouette pixels inside the image.
    pub px_in_image: u64,
    /// Visible pixels (BOP `px_count_visib`, delta 15 mm).
    pub px_visib: u64,
}

impl Visibility {
    /// BOP `visib_fract` (0 when the object covers no pixel).
    pub fn visib_fract(&self) -> f64 {
        if self.px_all == 0 {
            0.0
        } else {
            self.px_visib as f64 / self.px_all as f64
        }
    }
}

/// Counts the pixels of every target of a frame, occluded by the other targets, the
/// distractors and the ground. Implemented by synthgen-render (a depth-only raster pass), so
/// that core needs no renderer. Must be a pure function of the scene.
pub trait ViewCheck: Send + Sync {
    /// One entry per `scene.objects`, or why the check could not run.
    fn visibility(&self, scene: &FrameScene) -> Result<Vec<Visibility>, String>;
}

/// True when every extreme point of every target projects into the image with a pixel to
/// spare (pixel centres run 0..w-1; a silhouette pixel outside the image needs geometry
/// beyond -1 or w), and lies in front of the camera.
pub(crate) fn targets_inside_image(scene: &FrameScene, objects: &[&SceneObject]) -> bool {
    let k = &scene.intrinsics;
    let (w, h) = (f64::from(k.width) - 1.0, f64::from(k.height) - 1.0);
    scene.objects.iter().zip(objects).all(|(inst, o)| {
        o.support_points_m.iter().all(|p| {
            let q: DVec3 = inst.cam_from_obj.transform_point(p.as_dvec3());
            if q.z <= 0.01 {
                return false;
            }
            let u = k.fx * q.x / q.z + k.cx;
            let v = k.fy * q.y / q.z + k.cy;
            (0.0..=w).contains(&u) && (0.0..=h).contains(&v)
        })
    })
}
