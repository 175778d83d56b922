//! The BOP dataset format (bop_toolkit, BlenderProc): reader, writer and the exact JSON
//! text layout.

pub(crate) mod chunk;
pub mod image;
pub mod journal;
pub mod json;
pub mod merge;
pub mod reader;
pub mod types;
pub mod writer;

pub use chunk::{write_map, ChunkAnnotations, FrameRecord, SCENE_CAMERA, SCENE_GT, SCENE_GT_INFO};
pub use image::{
    read_depth_m, read_mask, read_rgb, read_rgb_sized, Plane, PngCompression, RgbFormat, RgbImage,
};
pub use reader::{BopDataset, BopScene};
pub use types::{CameraInfo, GtEntry, ModelInfo, SceneCamera};
pub use writer::{BopWriter, BopWriterOptions, DoneFrames, WriteSummary};
