//! Dataset formats of synthgen: the BOP reader and writer (byte-compatible with bop_toolkit
//! and BlenderProc), the Linemod (DenseFusion's Linemod_preprocessed) and YCB-Video (PoseCNN's
//! layout, MAT v5 `-meta.mat` through `synthgen-mat`) readers and writers, COCO export,
//! conversion between them, validation, masks and `scene_gt_info` of real frames from their GT
//! poses (`annotate`), one frame source over all layouts (`source`), the `synthgen.json`
//! manifest and atomic file output.
//!
//! What is done *with* datasets lives elsewhere: fitting synthgen to real captures (sensor and
//! scene fit) in `synthgen-fit`, mixing, statistics and previews in `synthgen-curate`.
//!
//! ```no_run
//! use std::path::Path;
//! use synthgen_core::{annotate, annotate::DEFAULT_VISIB_DELTA_M, FrameScene, RenderedFrame};
//! use synthgen_formats::bop::{BopDataset, BopWriter, BopWriterOptions};
//!
//! # fn frames() -> Vec<(FrameScene, RenderedFrame)> { vec![] }
//! # fn main() -> Result<(), synthgen_formats::Error> {
//! let root = Path::new("out/my_dataset");
//! let writer = BopWriter::create(root, BopWriterOptions::new(synthgen_core::Intrinsics::LINEMOD))?;
//! writer.write_camera_json()?;
//! for (scene, frame) in frames() {
//!     let ann = annotate(&scene.intrinsics, &frame.depth_m, &frame.alone, DEFAULT_VISIB_DELTA_M);
//!     let record = writer.write_frame(scene.frame_index, &scene, &frame, &ann)?;
//!     writer.add_record(record)?;
//! }
//! let summary = writer.finish()?;
//! println!("{} frames in scenes {:?}", summary.frames, summary.scenes);
//!
//! let ds = BopDataset::open(root)?;
//! let scene = ds.read_scene("train_pbr", 0)?;
//! for (im_id, gts) in &scene.gt {
//!     println!("image {im_id}: {} objects", gts.len());
//! }
//! # Ok(()) }
//! ```

pub mod annotate;
pub mod bop;
pub mod coco;
pub mod convert;
pub mod draw;
mod error;
pub mod fingerprint;
pub mod identity;
pub mod io;
pub mod layout;
pub mod linemod;
pub mod manifest;
pub mod output;
pub mod shared_frames;
pub mod source;
pub mod validate;
pub mod ycbv;

pub use error::{Error, Result};
pub use manifest::{read_manifest, write_manifest, Manifest};
