//! DenseFusion's `Linemod_preprocessed` layout: one folder per object under `data/`, each
//! with `rgb/`, `depth/` (uint16, value × `depth_scale` = mm), `mask/` (255 = object),
//! `gt.yml`, `info.yml`, `train.txt` and `test.txt`; `models/obj_{id:02d}.ply` (mm) and
//! `models/models_info.yml`. See docs/formats.md for how synthgen fills it.

pub mod images;
pub mod reader;
pub mod source;
pub mod writer;
mod yaml;

use serde::{Deserialize, Serialize};
use synthgen_core::Pose;

pub use reader::{
    read_gt_yml, read_id_list, read_info_yml, read_models_info_yml, LinemodDataset, LinemodFolder,
};
pub use writer::{LinemodFrame, LinemodObject, LinemodWriter, LinemodWriterOptions, ListFile};
pub use yaml::{gt_yml_text, info_yml_text, models_info_yml_text, yaml_float};

/// An object gets a folder entry for a frame when its visible fraction is at least this
/// (and above 0): BOP's convention for "visible enough to annotate" (COCO's ignore flag uses
/// the same 0.1).
pub const DEFAULT_MIN_VISIB_FRACT: f64 = 0.1;

/// `data/{obj:02d}` of an object id.
pub fn folder_name(obj_id: u32) -> String {
    format!("{obj_id:02}")
}

/// `{i:04d}.png` of a frame id.
pub fn frame_file(frame_id: u64) -> String {
    format!("{frame_id:04}.png")
}

/// One entry of a frame's list in `gt.yml`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinemodGt {
    /// Row-major rotation of `cam_from_obj`.
    #[serde(rename = "cam_R_m2c")]
    pub cam_r_m2c: [f64; 9],
    /// Translation of `cam_from_obj` in millimetres.
    pub cam_t_m2c: [f64; 3],
    /// `[x, y, w, h]` in pixels (synthgen writes BOP's `bbox_obj`).
    pub obj_bb: [i32; 4],
    pub obj_id: u32,
}

impl LinemodGt {
    /// `cam_from_obj` with the nearest proper rotation (see [`crate::bop::GtEntry::cam_from_obj`]).
    pub fn cam_from_obj(&self) -> Pose {
        self.cam_from_obj_as_stored().orthonormalized()
    }

    /// `cam_from_obj` exactly as `gt.yml` stores it.
    pub fn cam_from_obj_as_stored(&self) -> Pose {
        Pose::from_bop(&self.cam_r_m2c, &self.cam_t_m2c)
    }
}

/// One frame's entry of `info.yml`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinemodInfo {
    /// Row-major 3x3 intrinsics.
    #[serde(rename = "cam_K")]
    pub cam_k: [f64; 9],
    /// Depth PNG value × `depth_scale` = millimetres.
    pub depth_scale: f64,
}
