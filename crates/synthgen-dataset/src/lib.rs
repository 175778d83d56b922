//! Dataset formats of synthgen: the BOP reader and writer (byte-compatible with bop_toolkit
//! and BlenderProc), the Linemod (DenseFusion's Linemod_preprocessed) and YCB-Video (PoseCNN's
//! layout, MAT v5 `-meta.mat`) readers and writers, conversion between them, validation, the
//! `synthgen.json` manifest and atomic file output.
//!
//! ```no_run
//! use std::path::Path;
//! use synthgen_core::{annotate, annotate::DEFAULT_VISIB_DELTA_M, FrameScene, RenderedFrame};
//! use synthgen_dataset::bop::{BopDataset, BopWriter, BopWriterOptions};
//!
//! # fn frames() -> Vec<(FrameScene, RenderedFrame)> { vec![] }
//! # fn main() -> Result<(), synthgen_dataset::Error> {
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
pub mod io;
pub mod linemod;
pub mod manifest;
pub mod mix;
pub mod output;
pub mod preview;
pub mod rgb_compare;
pub mod scene_fit;
pub mod sensor;
pub mod shared_frames;
pub mod source;
pub mod stats;
pub mod validate;
pub mod ycbv;

pub use error::{Error, Result};
pub use manifest::{read_manifest, write_manifest, Manifest};
