//! A box detector for synthgen, so that the RGB pose models run on whole frames without GT
//! boxes: a centre-heatmap network over the frame ([`net`]), its training on a dataset's
//! visible boxes and its run over a dataset's frames ([`detector`]), and 2D detections in
//! BOP's exchange format ([`detections`]), which `synthgen eval --detections` crops from.
//!
//! ```no_run
//! use std::path::Path;
//! use candle_core::Device;
//! use synthgen_core::NoProgress;
//! use synthgen_detect::detector::{detect_frames, Detector};
//!
//! let det = Detector::load(Path::new("runs/det"), &Device::Cpu)?;
//! let ds = synthgen_formats::layout::open_source(Path::new("../shared/data/lmo"))?;
//! let (found, summary) = detect_frames(&det, ds.as_ref(), "test", 0.05, 10, &NoProgress)?;
//! synthgen_detect::detections::write_detections(Path::new("det.json"), &found)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod coco_eval;
pub mod detections;
pub mod detector;
pub mod net;
