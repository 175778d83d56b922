//! The records of BOP's JSON files, shared by the reader and the writer. Field names are the
//! files' keys; units are the files' (millimetres, pixels).

use serde::{Deserialize, Serialize};
use synthgen_core::{Intrinsics, Pose, Symmetries};

/// `camera.json` at the dataset root.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    pub cx: f64,
    pub cy: f64,
    /// Depth PNG value × `depth_scale` = millimetres. Optional in bop_toolkit; 1.0 if absent.
    #[serde(default = "one")]
    pub depth_scale: f64,
    pub fx: f64,
    pub fy: f64,
    pub height: u32,
    pub width: u32,
}

fn one() -> f64 {
    1.0
}

impl CameraInfo {
    pub fn new(k: &Intrinsics, depth_scale: f64) -> CameraInfo {
        CameraInfo {
            cx: k.cx,
            cy: k.cy,
            depth_scale,
            fx: k.fx,
            fy: k.fy,
            height: k.height,
            width: k.width,
        }
    }

    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
        }
    }
}

/// `-0.0` → `0.0`, so files do not show the sign of zeros that come out of inversions.
pub(crate) fn no_negative_zero(v: f64) -> f64 {
    v + 0.0
}

/// One entry of `models/models_info.json` (millimetres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    pub diameter: f64,
    pub min_x: f64,
    pub min_y: f64,
    pub min_z: f64,
    pub size_x: f64,
    pub size_y: f64,
    pub size_z: f64,
    /// `symmetries_discrete` / `symmetries_continuous`, omitted when empty.
    #[serde(flatten)]
    pub symmetries: Symmetries,
}

impl ModelInfo {
    /// Extents and diameter of a model (metres in, millimetres out), no symmetries.
    pub fn from_model(model: &synthgen_core::Model) -> ModelInfo {
        let (min, size) = model.aabb().map_or(([0.0; 3], [0.0; 3]), |bb| {
            (
                bb.min.as_dvec3().to_array().map(|v| v * 1000.0),
                bb.size().as_dvec3().to_array().map(|v| v * 1000.0),
            )
        });
        ModelInfo {
            diameter: model.diameter_m() * 1000.0,
            min_x: min[0],
            min_y: min[1],
            min_z: min[2],
            size_x: size[0],
            size_y: size[1],
            size_z: size[2],
            symmetries: Symmetries::default(),
        }
    }
}

/// One image's entry of `scene_camera.json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SceneCamera {
    /// Row-major 3x3 intrinsics.
    #[serde(rename = "cam_K")]
    pub cam_k: [f64; 9],
    /// Row-major rotation of `cam_from_world`.
    #[serde(rename = "cam_R_w2c", default, skip_serializing_if = "Option::is_none")]
    pub cam_r_w2c: Option<[f64; 9]>,
    /// Translation of `cam_from_world` in millimetres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cam_t_w2c: Option<[f64; 3]>,
    pub depth_scale: f64,
}

impl SceneCamera {
    /// A camera with intrinsics `cam_k` (row-major) and no world pose (Linemod's frames,
    /// test fixtures).
    pub fn without_world(cam_k: [f64; 9], depth_scale: f64) -> SceneCamera {
        SceneCamera {
            cam_k,
            cam_r_w2c: None,
            cam_t_w2c: None,
            depth_scale,
        }
    }

    pub fn intrinsics(&self, width: u32, height: u32) -> Intrinsics {
        Intrinsics::from_k(&self.cam_k, width, height)
    }

    /// `cam_from_world`, when the file has it, with the nearest proper rotation (files store
    /// approximate ones; see [`synthgen_core::pose`]).
    pub fn cam_from_world(&self) -> Option<Pose> {
        Some(Pose::from_bop(&self.cam_r_w2c?, &self.cam_t_w2c?).orthonormalized())
    }
}

/// One object instance of `scene_gt.json`; its index in the image's list is the gt id.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GtEntry {
    /// Row-major rotation of `cam_from_obj`.
    #[serde(rename = "cam_R_m2c")]
    pub cam_r_m2c: [f64; 9],
    /// Translation of `cam_from_obj` in millimetres.
    pub cam_t_m2c: [f64; 3],
    pub obj_id: u32,
}

impl GtEntry {
    pub fn new(obj_id: u32, cam_from_obj: &Pose) -> GtEntry {
        GtEntry {
            cam_r_m2c: cam_from_obj.rotation_row_major().map(no_negative_zero),
            cam_t_m2c: cam_from_obj.translation_mm().map(no_negative_zero),
            obj_id,
        }
    }

    /// `cam_from_obj` with the nearest proper rotation (the file's may be approximate; see
    /// [`synthgen_core::pose`]). Writers copy `cam_r_m2c` itself, keeping the file's numbers.
    pub fn cam_from_obj(&self) -> Pose {
        self.cam_from_obj_as_stored().orthonormalized()
    }

    /// `cam_from_obj` exactly as the file stores it.
    pub fn cam_from_obj_as_stored(&self) -> Pose {
        Pose::from_bop(&self.cam_r_m2c, &self.cam_t_m2c)
    }
}
