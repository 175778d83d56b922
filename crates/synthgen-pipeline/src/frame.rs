//! A rendered, annotated frame in memory: what a writer would put on disk, before encoding.

use synthgen_core::{FrameScene, GtInfo, Intrinsics, ObjectAnnotation, Pose, RenderedFrame};

/// One frame: images after the sensor model, annotations from the clean render.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The global frame index (the one the sampler and the sensor's noise are seeded with).
    pub index: u64,
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    /// World: z up, the ground plane at z = 0.
    pub world_from_cam: Pose,
    /// `width * height * 3` sRGB bytes, row-major.
    pub rgb: Vec<u8>,
    /// Depth along the optical axis in metres after the sensor model, as written to disk
    /// (before quantization); 0 = no reading.
    pub depth_m: Vec<f32>,
    /// Per pixel: 0 for background, ground, walls and distractors, `k + 1` for `objects[k]`.
    pub instance_ids: Vec<u16>,
    /// The annotated objects, in the order of BOP's `scene_gt` (gt id k = `objects[k]`).
    pub objects: Vec<FrameObject>,
}

/// One annotated object of a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameObject {
    pub obj_id: u32,
    /// Rotation and translation in metres, OpenCV camera frame.
    pub cam_from_obj: Pose,
    /// Full silhouette inside the image, as if the object were alone: 0 or 255 per pixel,
    /// BOP's `mask/`.
    pub mask: Vec<u8>,
    /// The visible part (bop19 rule): 0 or 255 per pixel, BOP's `mask_visib/`.
    pub mask_visib: Vec<u8>,
    /// BOP's `scene_gt_info` entry: boxes, pixel counts, `visib_fract`.
    pub info: GtInfo,
}

impl Frame {
    pub(crate) fn new(
        scene: &FrameScene,
        frame: RenderedFrame,
        ann: Vec<ObjectAnnotation>,
    ) -> Frame {
        let objects = scene
            .objects
            .iter()
            .zip(ann)
            .map(|(o, a)| FrameObject {
                obj_id: o.obj_id,
                cam_from_obj: o.cam_from_obj,
                mask: a.mask,
                mask_visib: a.mask_visib,
                info: a.info,
            })
            .collect();
        Frame {
            index: scene.frame_index,
            width: frame.width,
            height: frame.height,
            intrinsics: scene.intrinsics,
            world_from_cam: scene.world_from_cam,
            rgb: frame.rgb,
            depth_m: frame.depth_m,
            instance_ids: frame.instance,
            objects,
        }
    }

    /// BOP's `cam_K`: the intrinsics matrix, row-major.
    pub fn cam_k(&self) -> [f64; 9] {
        self.intrinsics.k_row_major()
    }
}
